// `htfeti spectrum`: prints the paper's Table 1 quantities for one cluster (see spectrum.hpp).
#include "htfeti/spectrum.hpp"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "htfeti/parallel/blas_buffers.hpp"

namespace htfeti {

int run_spectrum(int m, int n, const std::string& element, bool json) {
  if (const std::string error = reserve_blas_buffers(); !error.empty())
    throw std::invalid_argument(error);
  const ClusterSpectrum s = cluster_spectrum(m, n, parse_element(element));
  if (json) {
    nlohmann::json j = {{"m", s.m},
                        {"elements", s.n},
                        {"element", element},
                        {"H_over_h", s.H_over_h},
                        {"dimension", s.dimension},
                        {"lambda_max", s.lambda_max},
                        {"lambda_min", s.lambda_min},
                        {"lambda_min_estimate", s.lambda_min_estimate},
                        {"subdomain_lambda_max", s.subdomain_lambda_max},
                        {"subdomain_lambda_min", s.subdomain_lambda_min}};
    std::printf("%s\n", j.dump().c_str());
    return 0;
  }
  std::printf("cluster of %d x %d subdomains joined by edge averages, h = 1/%d, %s elements\n", m,
              m, n, element.c_str());
  std::printf("  m                      %d\n", s.m);
  std::printf("  H_s/h                  %d\n", s.H_over_h);
  std::printf("  lambda_max(S~)         %.4f\n", s.lambda_max);
  std::printf("  lambda_min(S~)         %.4g\n", s.lambda_min);
  std::printf("  estimate (19)          %.4g\n", s.lambda_min_estimate);
  std::printf("  (one subdomain's S: lambda_min %.4g, lambda_max %.4f; dim S~ = %d)\n",
              s.subdomain_lambda_min, s.subdomain_lambda_max, s.dimension);
  return 0;
}

}  // namespace htfeti
