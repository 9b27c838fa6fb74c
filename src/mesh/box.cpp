#include "htfeti/mesh/box.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace htfeti {

namespace {
const char* axis_name(int d) { return d == 0 ? "x" : d == 1 ? "y" : "z"; }
}  // namespace

BoxGrid::BoxGrid(const BoxGridOptions& o) : o_(o) {
  if (o.dim != 2 && o.dim != 3) throw std::invalid_argument("the dimension must be 2 or 3");
  if (cell_dimension(o.cell) != o.dim)
    throw std::invalid_argument("element " + to_string(o.cell) + " does not fit a " +
                                std::to_string(o.dim) + "D box (2D: quad4, tri3; 3D: hex8, tet4)");
  if (o.boxes < 1) throw std::invalid_argument("the number of boxes must be positive");
  if (o.cluster_size <= 0) throw std::invalid_argument("the cluster size must be positive");
  for (int d = 0; d < o.dim; ++d) {
    if (!(o.size[d] > 0) || !std::isfinite(o.size[d]))
      throw std::invalid_argument(std::string("the box size along ") + axis_name(d) +
                                  " must be positive and finite");
    if (o.elements[d] <= 0)
      throw std::invalid_argument(std::string("the number of elements along ") + axis_name(d) +
                                  " must be positive");
    if (o.subdomains[d] <= 0)
      throw std::invalid_argument(std::string("the number of subdomains along ") + axis_name(d) +
                                  " must be positive");
    if (o.elements[d] % o.subdomains[d] != 0)
      throw std::invalid_argument(std::to_string(o.elements[d]) + " elements along " +
                                  axis_name(d) + " are not divisible by " +
                                  std::to_string(o.subdomains[d]) + " subdomains");
    if (o.subdomains[d] % o.cluster_size != 0)
      throw std::invalid_argument(std::to_string(o.subdomains[d]) + " subdomains along " +
                                  axis_name(d) + " are not divisible by the cluster size " +
                                  std::to_string(o.cluster_size));
  }
  for (int d = o.dim; d < 3; ++d) o_.elements[d] = o_.subdomains[d] = 1, o_.size[d] = 0;
  // Counts that must fit the int indices used per subdomain and for subdomain ids.
  const double nodes_sub = static_cast<double>(nodes_per_subdomain());
  if (nodes_sub * (o.dim == 2 ? 2 : 3) > 2.0e9)
    throw std::invalid_argument("a subdomain with " + std::to_string(nodes_per_subdomain()) +
                                " nodes is too large (use more subdomains)");
  if (static_cast<double>(num_subdomains()) > 1.0e9)
    throw std::invalid_argument("too many subdomains (" + std::to_string(num_subdomains()) + ")");
}

int BoxGrid::subdomains_per_cluster() const {
  int m = o_.cluster_size, r = m * m;
  return o_.dim == 3 ? r * m : r;
}

long long BoxGrid::num_subdomains() const {
  return 1LL * o_.boxes * o_.subdomains[0] * o_.subdomains[1] * o_.subdomains[2];
}

long long BoxGrid::num_clusters() const { return num_subdomains() / subdomains_per_cluster(); }

long long BoxGrid::nodes_per_box() const {
  return (o_.elements[0] + 1LL) * (o_.elements[1] + 1LL) * (o_.dim == 3 ? o_.elements[2] + 1LL : 1);
}

long long BoxGrid::nodes_per_subdomain() const {
  return (H(0) + 1LL) * (H(1) + 1LL) * (o_.dim == 3 ? H(2) + 1LL : 1);
}

long long BoxGrid::cells_per_subdomain() const {
  long long c = 1LL * H(0) * H(1) * (o_.dim == 3 ? H(2) : 1);
  if (o_.cell == CellType::tri3) c *= 2;
  if (o_.cell == CellType::tet4) c *= 6;
  return c;
}

BoxGrid::Position BoxGrid::position(long long s) const {
  const int m = o_.cluster_size, per = subdomains_per_cluster();
  const long long c = s / per;
  const int local = static_cast<int>(s % per);
  const long long ncx = clusters_along(0), ncy = clusters_along(1),
                  ncz = o_.dim == 3 ? clusters_along(2) : 1;
  const long long cx = c % ncx, cy = (c / ncx) % ncy, cz = (c / (ncx * ncy)) % ncz;
  const int q = static_cast<int>(c / (ncx * ncy * ncz));
  const int lx = local % m, ly = (local / m) % m, lz = o_.dim == 3 ? local / (m * m) : 0;
  return {q,
          {static_cast<int>(cx * m + lx), static_cast<int>(cy * m + ly),
           static_cast<int>(o_.dim == 3 ? cz * m + lz : 0)}};
}

long long BoxGrid::subdomain_id(int q, std::array<int, 3> s) const {
  const int m = o_.cluster_size;
  const long long ncx = clusters_along(0), ncy = clusters_along(1),
                  ncz = o_.dim == 3 ? clusters_along(2) : 1;
  const long long c = ((q * ncz + s[2] / m) * ncy + s[1] / m) * ncx + s[0] / m;
  const int local =
      o_.dim == 3 ? ((s[2] % m) * m + s[1] % m) * m + s[0] % m : (s[1] % m) * m + s[0] % m;
  return c * subdomains_per_cluster() + local;
}

long long BoxGrid::global_node(int q, std::array<long long, 3> g) const {
  return q * nodes_per_box() + (g[2] * (o_.elements[1] + 1LL) + g[1]) * (o_.elements[0] + 1LL) +
         g[0];
}

int BoxGrid::node_copies(int q, const long long* g, int* out) const {
  int lists[3][2], counts[3];
  for (int d = 0; d < 3; ++d) {
    counts[d] = 0;
    if (d >= o_.dim) {
      lists[d][counts[d]++] = 0;
      continue;
    }
    const long long gd = g[d];
    const int Hd = H(d);
    if (gd % Hd == 0) {
      if (gd / Hd - 1 >= 0) lists[d][counts[d]++] = static_cast<int>(gd / Hd - 1);
      if (gd / Hd < o_.subdomains[d]) lists[d][counts[d]++] = static_cast<int>(gd / Hd);
    } else {
      lists[d][counts[d]++] = static_cast<int>(gd / Hd);
    }
  }
  int k = 0;
  for (int z = 0; z < counts[2]; ++z)
    for (int y = 0; y < counts[1]; ++y)
      for (int x = 0; x < counts[0]; ++x)
        out[k++] = static_cast<int>(subdomain_id(q, {lists[0][x], lists[1][y], lists[2][z]}));
  return k;
}

bool BoxGrid::on_boundary(const long long* g) const {
  for (int d = 0; d < o_.dim; ++d)
    if (g[d] == 0 || g[d] == o_.elements[d]) return true;
  return false;
}

SubdomainMesh BoxGrid::mesh(int sub) const {
  SubdomainMesh m;
  const Position p = position(sub);
  const int dim = o_.dim;
  const int Hx = H(0), Hy = H(1), Hz = dim == 3 ? H(2) : 0;
  const int nx = Hx + 1, ny = Hy + 1, nz = Hz + 1;
  const int nn = nx * ny * nz;
  m.id = sub;
  m.cluster = static_cast<int>(cluster_of(sub));
  m.dim = dim;
  m.type = o_.cell;
  m.uniform_period = o_.cell == CellType::tri3 ? 2 : o_.cell == CellType::tet4 ? 6 : 1;
  m.coords.resize(3 * static_cast<size_t>(nn));
  m.global_node.resize(nn);
  m.copy_offset.resize(nn + 1);
  m.on_boundary.assign(nn, 0);
  m.copy_list.reserve(nn);
  const double h[3] = {o_.size[0] / o_.elements[0], o_.size[1] / o_.elements[1],
                       dim == 3 ? o_.size[2] / o_.elements[2] : 0.0};
  for (int d = 0; d < 3; ++d) m.uniform_spacing[d] = h[d];
  const int Hs[3] = {Hx, Hy, Hz};
  static const char* face[3][2] = {{"x0", "x1"}, {"y0", "y1"}, {"z0", "z1"}};
  for (int c = 0; c < nz; ++c)
    for (int b = 0; b < ny; ++b)
      for (int a = 0; a < nx; ++a) {
        const int k = (c * ny + b) * nx + a;
        const long long g[3] = {1LL * p.s[0] * Hx + a, 1LL * p.s[1] * Hy + b,
                                dim == 3 ? 1LL * p.s[2] * Hz + c : 0};
        // Coordinates as the 2D built-ins always computed them: q + (s H + a) h.
        m.coords[3 * k] = p.q * o_.size[0] + g[0] * h[0];
        m.coords[3 * k + 1] = g[1] * h[1];
        m.coords[3 * k + 2] = dim == 3 ? g[2] * h[2] : 0.0;
        m.global_node[k] = global_node(p.q, {g[0], g[1], g[2]});
        for (int d = 0; d < dim; ++d)
          if (g[d] == 0 || g[d] == o_.elements[d]) {
            m.on_boundary[k] = 1;
            m.node_groups[face[d][g[d] == 0 ? 0 : 1]].push_back(k);
          }
        m.copy_offset[k] = static_cast<int>(m.copy_list.size());
        // A node inside the subdomain has no other copy (node_copies would find only `sub`,
        // after ten integer divisions per node).
        const bool inside = a > 0 && a < Hx && b > 0 && b < Hy && (dim == 2 || (c > 0 && c < Hz));
        if (inside) {
          m.copy_list.push_back(sub);
        } else {
          int cp[8];
          const int kc = node_copies(p.q, g, cp);
          m.copy_list.insert(m.copy_list.end(), cp, cp + kc);
        }
      }
  m.copy_offset[nn] = static_cast<int>(m.copy_list.size());

  // Cells.
  auto node = [&](int a, int b, int c) { return (c * ny + b) * nx + a; };
  m.cells.reserve(static_cast<size_t>(cells_per_subdomain()) * cell_nodes(o_.cell));
  for (int c = 0; c < std::max(Hz, 1); ++c)
    for (int b = 0; b < Hy; ++b)
      for (int a = 0; a < Hx; ++a) {
        if (dim == 2) {
          const int n0 = node(a, b, 0), n1 = node(a + 1, b, 0), n2 = node(a + 1, b + 1, 0),
                    n3 = node(a, b + 1, 0);
          if (o_.cell == CellType::quad4)
            m.cells.insert(m.cells.end(), {n0, n1, n2, n3});
          else
            m.cells.insert(m.cells.end(), {n0, n1, n2, n0, n2, n3});
          continue;
        }
        const int v[8] = {node(a, b, c),
                          node(a + 1, b, c),
                          node(a + 1, b + 1, c),
                          node(a, b + 1, c),
                          node(a, b, c + 1),
                          node(a + 1, b, c + 1),
                          node(a + 1, b + 1, c + 1),
                          node(a, b + 1, c + 1)};
        if (o_.cell == CellType::hex8) {
          m.cells.insert(m.cells.end(), v, v + 8);
        } else {
          static const int tets[6][4] = {{0, 1, 2, 6}, {0, 2, 3, 6}, {0, 3, 7, 6},
                                         {0, 7, 4, 6}, {0, 4, 5, 6}, {0, 5, 1, 6}};
          for (const auto& t : tets)
            m.cells.insert(m.cells.end(), {v[t[0]], v[t[1]], v[t[2]], v[t[3]]});
        }
      }

  // Boundary facets of the faces of the box that this subdomain touches.
  for (int d = 0; d < dim; ++d)
    for (int side = 0; side < 2; ++side) {
      const bool touches = side == 0 ? p.s[d] == 0 : p.s[d] == o_.subdomains[d] - 1;
      if (!touches) continue;
      auto& fg = m.facet_groups[face[d][side]];
      const int fixed = side == 0 ? 0 : Hs[d];
      const int e1 = (d + 1) % dim, e2 = (d + 2) % 3;  // the other axes (2D: one)
      int idx[3];
      idx[d] = fixed;
      if (dim == 2) {
        fg.facet_nodes = 2;
        for (int t = 0; t < Hs[e1]; ++t) {
          idx[e1] = t;
          const int na = node(idx[0], idx[1], 0);
          idx[e1] = t + 1;
          const int nb = node(idx[0], idx[1], 0);
          fg.nodes.insert(fg.nodes.end(), {na, nb});
        }
        continue;
      }
      const int f1 = (d + 1) % 3, f2 = (d + 2) % 3;
      (void)e2;
      fg.facet_nodes = o_.cell == CellType::hex8 ? 4 : 3;
      for (int t = 0; t < Hs[f2]; ++t)
        for (int r = 0; r < Hs[f1]; ++r) {
          int q[4];
          const int corners[4][2] = {{r, t}, {r + 1, t}, {r + 1, t + 1}, {r, t + 1}};
          for (int i = 0; i < 4; ++i) {
            idx[f1] = corners[i][0], idx[f2] = corners[i][1];
            q[i] = node(idx[0], idx[1], idx[2]);
          }
          if (o_.cell == CellType::hex8)
            fg.nodes.insert(fg.nodes.end(), q, q + 4);
          else  // the tet split cuts every face along the diagonal through its lowest corner
            fg.nodes.insert(fg.nodes.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
        }
    }
  return m;
}

}  // namespace htfeti
