#include "htfeti/feti/input.hpp"

#include <algorithm>
#include <stdexcept>

namespace htfeti {

Glue parse_glue(const std::string& name) { return parse_name(kGlueNames, name, "glue"); }

std::string to_string(Glue value) { return name_of(kGlueNames, value); }

int FetiLayout::cluster_of(int s) const {
  return static_cast<int>(std::upper_bound(cluster_first.begin(), cluster_first.end(), s) -
                          cluster_first.begin()) -
         1;
}

std::pair<int, int> FetiLayout::cluster_range(int r, int P) const {
  const long long nc = num_clusters;
  return {static_cast<int>(nc * r / P), static_cast<int>(nc * (r + 1) / P)};
}

int FetiLayout::rank_of_cluster(int c, int P) const {
  const long long nc = num_clusters;
  int r = static_cast<int>((static_cast<long long>(c) * P + P - 1) / nc);
  r = std::min(std::max(r, 0), P - 1);
  while (r > 0 && cluster_range(r, P).first > c) --r;
  while (r < P - 1 && cluster_range(r, P).second <= c) ++r;
  return r;
}

}  // namespace htfeti
