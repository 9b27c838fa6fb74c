#include "htfeti/model/decomposition.hpp"

#include <stdexcept>

namespace htfeti {

Decomposition::Decomposition(const DecompositionOptions& o) : opt_(o) {
  if (o.elements <= 0) throw std::invalid_argument("--elements must be positive");
  if (o.subdomains <= 0) throw std::invalid_argument("--subdomains must be positive");
  if (o.cluster_size <= 0) throw std::invalid_argument("--cluster-size must be positive");
  if (1LL * o.subdomains * o.subdomains * 2 > 1000000000LL)
    throw std::invalid_argument("--subdomains " + std::to_string(o.subdomains) + " is too large");
  if (o.elements % o.subdomains != 0)
    throw std::invalid_argument("--elements " + std::to_string(o.elements) +
                                " is not divisible by --subdomains " +
                                std::to_string(o.subdomains));
  if (o.subdomains % o.cluster_size != 0)
    throw std::invalid_argument("--subdomains " + std::to_string(o.subdomains) +
                                " is not divisible by --cluster-size " +
                                std::to_string(o.cluster_size));
  if (nodes_per_subdomain() > 500000000LL)
    throw std::invalid_argument("a subdomain of " + std::to_string(H()) + " x " +
                                std::to_string(H()) +
                                " elements is too large (use more subdomains)");
  if (glue_averages() && H() < 2)
    throw std::invalid_argument(
        "gluing by edge averages needs at least 2 elements per subdomain side (edge interiors "
        "are empty otherwise); use --glue corners or fewer subdomains");
}

BoxGrid Decomposition::grid() const {
  BoxGridOptions g;
  g.dim = 2;
  g.cell = opt_.element == ElementKind::q1 ? CellType::quad4 : CellType::tri3;
  g.boxes = squares();
  g.size = {1, 1, 1};
  g.elements = {n(), n(), 1};
  g.subdomains = {ns(), ns(), 1};
  g.cluster_size = m();
  return BoxGrid(g);
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
