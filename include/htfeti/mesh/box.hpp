// Generated box meshes, decomposed without any global mesh: every rank generates only the
// subdomains it owns, by arithmetic.
//
// One box [0, size_x] x [0, size_y] (x [0, size_z]) or several boxes side by side along x, each
// with nodes of its own (box q is shifted by q * size_x; the two membranes of the paper are two
// unit squares). Each box has elements[d] elements along axis d and is cut into subdomains[d]
// subdomain boxes, grouped into clusters of m x m (x m) subdomains.
//
// Numbering is cluster-major so that a contiguous range of subdomain ids is a contiguous range of
// clusters: cluster id = ((q * nc_z + cz) * nc_y + cy) * nc_x + cx, subdomain id =
// cluster * m^dim + (lz * m + ly) * m + lx. Global node id: q * nodes_per_box +
// (gz * (n_y + 1) + gy) * (n_x + 1) + gx; subdomain-local node (c * (H_y + 1) + b) * (H_x + 1) + a.
// Copies of a node are listed in geometric order (z, then y, then x of the subdomain).
// Cells: quad4/hex8 per grid cell; tri3 splits a square by its diagonal from the lower-left to
// the upper-right corner, tet4 splits a cube into six tetrahedra around its main diagonal
// (conforming between neighbours). Named groups: the faces x0 x1 y0 y1 (z0 z1) of every box.
#pragma once

#include <array>
#include <utility>

#include "htfeti/mesh/subdomain_mesh.hpp"

namespace htfeti {

struct BoxGridOptions {
  int dim = 2;
  CellType cell = CellType::quad4;
  int boxes = 1;
  std::array<double, 3> size{1, 1, 1};
  std::array<int, 3> elements{1, 1, 1};
  std::array<int, 3> subdomains{1, 1, 1};
  int cluster_size = 1;
};

class BoxGrid {
 public:
  /// Validates; throws std::invalid_argument naming the problem.
  explicit BoxGrid(const BoxGridOptions& options);
  const BoxGridOptions& options() const { return o_; }
  int dim() const { return o_.dim; }
  int H(int d) const { return o_.elements[d] / o_.subdomains[d]; }
  int clusters_along(int d) const { return o_.subdomains[d] / o_.cluster_size; }
  int subdomains_per_cluster() const;
  long long num_subdomains() const;
  long long num_clusters() const;
  long long nodes_per_box() const;
  long long num_nodes() const { return o_.boxes * nodes_per_box(); }
  long long nodes_per_subdomain() const;
  long long cells_per_subdomain() const;

  struct Position {
    int q;
    std::array<int, 3> s;  ///< subdomain indices along x, y, z within box q
  };
  Position position(long long subdomain) const;
  long long subdomain_id(int q, std::array<int, 3> s) const;
  long long cluster_of(long long subdomain) const { return subdomain / subdomains_per_cluster(); }
  long long global_node(int q, std::array<long long, 3> g) const;

  /// Subdomains whose closure holds grid node g of box q, in geometric order; returns the count
  /// (at most 8).
  int node_copies(int q, const long long* g, int* out) const;
  /// Whether grid node g lies on the boundary of its box.
  bool on_boundary(const long long* g) const;

  SubdomainMesh mesh(int subdomain) const;

 private:
  BoxGridOptions o_;
};

}  // namespace htfeti
