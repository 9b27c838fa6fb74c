#include "htfeti/decomposition/decomposition.hpp"

#include <stdexcept>

namespace htfeti {

Glue parse_glue(const std::string& name) {
  if (name == "corners") return Glue::corners;
  if (name == "averages") return Glue::averages;
  if (name == "corners+averages") return Glue::corners_averages;
  throw std::invalid_argument("unknown glue '" + name +
                              "' (expected corners, averages or corners+averages)");
}

std::string to_string(Glue glue) {
  switch (glue) {
    case Glue::corners:
      return "corners";
    case Glue::averages:
      return "averages";
    case Glue::corners_averages:
      return "corners+averages";
  }
  return "?";
}

Decomposition::Decomposition(const DecompositionOptions& o) : opt_(o) {
  if (o.elements <= 0) throw std::invalid_argument("--elements must be positive");
  if (o.subdomains <= 0) throw std::invalid_argument("--subdomains must be positive");
  if (o.cluster_size <= 0) throw std::invalid_argument("--cluster-size must be positive");
  if (o.elements % o.subdomains != 0)
    throw std::invalid_argument("--elements " + std::to_string(o.elements) +
                                " is not divisible by --subdomains " +
                                std::to_string(o.subdomains));
  if (o.subdomains % o.cluster_size != 0)
    throw std::invalid_argument("--subdomains " + std::to_string(o.subdomains) +
                                " is not divisible by --cluster-size " +
                                std::to_string(o.cluster_size));
  if (glue_averages() && H() < 2)
    throw std::invalid_argument(
        "gluing by edge averages needs at least 2 elements per subdomain side (edge interiors "
        "are empty otherwise); use --glue corners or fewer subdomains");
}

SubdomainPosition Decomposition::position(int s) const {
  const int mm = m() * m(), nc = clusters_per_side();
  const int c = s / mm, local = s % mm;
  const int q = c / (nc * nc), cy = (c / nc) % nc, cx = c % nc;
  return {q, cx * m() + local % m(), cy * m() + local / m()};
}

int Decomposition::subdomain_id(int q, int sx, int sy) const {
  const int nc = clusters_per_side();
  const int c = (q * nc + sy / m()) * nc + sx / m();
  return c * m() * m() + (sy % m()) * m() + sx % m();
}

std::pair<int, int> Decomposition::cluster_range(int r, int P) const {
  const long long nc = num_clusters();
  return {static_cast<int>(nc * r / P), static_cast<int>(nc * (r + 1) / P)};
}

int Decomposition::rank_of_cluster(int c, int P) const {
  // Inverse of cluster_range: the r with nc*r/P <= c < nc*(r+1)/P.
  const long long nc = num_clusters();
  int r = static_cast<int>((static_cast<long long>(c) * P + P - 1) / nc);
  while (r > 0 && cluster_range(r, P).first > c) --r;
  while (cluster_range(r, P).second <= c) ++r;
  return r;
}

}  // namespace htfeti
