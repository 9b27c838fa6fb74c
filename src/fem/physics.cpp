#include "htfeti/fem/physics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <stdexcept>
#include <string>

#include "htfeti/expression.hpp"
#include "htfeti/fem/grid_offsets.hpp"
#include "htfeti/parallel/fresh_pages.hpp"

namespace htfeti {

PhysicsKind parse_physics(const std::string& name) {
  return parse_name(kPhysicsNames, name, "physics");
}

std::string to_string(PhysicsKind value) { return name_of(kPhysicsNames, value); }

void Physics::validate() const {
  if (dim != 2 && dim != 3) throw std::invalid_argument("the dimension must be 2 or 3");
  if (kind != PhysicsKind::elasticity) return;
  if (!(material.young > 0) || !std::isfinite(material.young))
    throw std::invalid_argument("physics.young must be positive and finite");
  if (!(material.poisson > -1 && material.poisson < 0.5))
    throw std::invalid_argument("physics.poisson must lie in (-1, 0.5)");
  if (!(density >= 0) || !std::isfinite(density))
    throw std::invalid_argument("physics.density must be non-negative and finite");
  for (double g : gravity)
    if (!std::isfinite(g)) throw std::invalid_argument("physics.gravity must be finite");
}

Eigen::MatrixXd physics_kernel(const Physics& ph, const double* xyz, int n) {
  if (ph.kind == PhysicsKind::laplace) return Eigen::MatrixXd::Ones(n, 1);
  double c[3] = {0, 0, 0};
  for (int k = 0; k < n; ++k)
    for (int d = 0; d < 3; ++d) c[d] += xyz[3 * k + d] / n;
  const int dim = ph.dim;
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(dim * n, ph.kernel_dimension());
  for (int k = 0; k < n; ++k) {
    const double x = xyz[3 * k] - c[0], y = xyz[3 * k + 1] - c[1], z = xyz[3 * k + 2] - c[2];
    if (dim == 2) {
      R(2 * k, 0) = 1, R(2 * k + 1, 1) = 1;
      R(2 * k, 2) = -y, R(2 * k + 1, 2) = x;
    } else {
      R(3 * k, 0) = 1, R(3 * k + 1, 1) = 1, R(3 * k + 2, 2) = 1;
      R(3 * k, 3) = -y, R(3 * k + 1, 3) = x;      // rotation about z
      R(3 * k + 1, 4) = -z, R(3 * k + 2, 4) = y;  // about x
      R(3 * k, 5) = z, R(3 * k + 2, 5) = -x;      // about y
    }
  }
  return R;
}

namespace {

// On a generated grid (the spacing set): replaces the n points xyz (3 each) by their offsets
// from `origin` in whole multiples of the spacing, the same at every position of the box (the
// coordinates g h round differently at each position, which made equal subdomains differ in
// their last bits and in their fixed dofs, so that they could not share a factor). Returns
// false, leaving xyz alone, on a general mesh.
bool grid_offsets(const SubdomainMesh& mesh, double* xyz, int n, const double origin[3]) {
  if (mesh.uniform_period == 0 || !(mesh.uniform_spacing[0] > 0)) return false;
  htfeti::grid_offsets(mesh.uniform_spacing, xyz, xyz, n, origin);
  return true;
}

// Element matrix of cell e (coordinates gathered); for uniform meshes the first one is reused.
Eigen::MatrixXd element_matrix(const SubdomainMesh& mesh, const Physics& ph, int e) {
  const int nc = cell_nodes(mesh.type);
  double x[24];
  for (int a = 0; a < nc; ++a) {
    const int k = mesh.cells[static_cast<size_t>(e) * nc + a];
    for (int d = 0; d < 3; ++d) x[3 * a + d] = mesh.coords[3 * static_cast<size_t>(k) + d];
  }
  const bool laplace2d = ph.kind == PhysicsKind::laplace && mesh.dim == 2;
  if (!laplace2d) {  // on a grid: the cell relative to its first node
    const double x0[3] = {x[0], x[1], x[2]};
    grid_offsets(mesh, x, nc, x0);
  }
  if (ph.kind == PhysicsKind::laplace) {
    // In 2D the Laplace element matrix does not depend on the cell's scale: compute it on the
    // cell scaled by its first edge (a grid square becomes the unit square exactly).
    if (mesh.dim == 2) {
      const double dx = x[3] - x[0], dy = x[4] - x[1], s = std::sqrt(dx * dx + dy * dy);
      const double x0 = x[0], y0 = x[1];
      for (int a = 0; a < nc; ++a)
        x[3 * a] = (x[3 * a] - x0) / s, x[3 * a + 1] = (x[3 * a + 1] - y0) / s;
    }
    return laplace_stiffness(mesh.type, x);
  }
  return elasticity_stiffness(mesh.type, x, ph.material);
}

}  // namespace

double cell_coefficient(const Expression& field, CellType type, const std::vector<double>& coords,
                        const int* cell) {
  const int nc = cell_nodes(type);
  double x[24];
  for (int a = 0; a < nc; ++a)
    for (int d = 0; d < 3; ++d) x[3 * a + d] = coords[3 * static_cast<size_t>(cell[a]) + d];
  const auto c = cell_centroid(type, x);
  const double value = field(c);
  if (!(value > 0))
    throw std::invalid_argument("physics.coefficient must be positive; it is " +
                                std::to_string(value) + " at (" + std::to_string(c[0]) + ", " +
                                std::to_string(c[1]) + ", " + std::to_string(c[2]) + ")");
  return value;
}

namespace {

// Calls visit(e, ke, scale) for every cell: its element matrix (computed once per period on a
// generated grid) and the coefficient at its centroid (1 without a coefficient field).
template <class Visit>
void for_each_element_matrix(const SubdomainMesh& mesh, const Physics& ph, Visit&& visit) {
  const int nc = cell_nodes(mesh.type), ne = mesh.num_cells();
  const int period = mesh.uniform_period;
  std::vector<Eigen::MatrixXd> cache(period > 0 ? std::min(period, ne) : 0);
  for (size_t e = 0; e < cache.size(); ++e)
    cache[e] = element_matrix(mesh, ph, static_cast<int>(e));
  Eigen::MatrixXd local;
  std::unique_ptr<Expression> coefficient;  // one per call: Expression is not thread-safe
  if (!ph.coefficient.empty()) coefficient = std::make_unique<Expression>(ph.coefficient);
  for (int e = 0; e < ne; ++e) {
    if (period == 0) local = element_matrix(mesh, ph, e);
    const Eigen::MatrixXd& ke = period > 0 ? cache[e % period] : local;
    const int* cn = mesh.cells.data() + static_cast<size_t>(e) * nc;
    const double scale =
        coefficient ? cell_coefficient(*coefficient, mesh.type, mesh.coords, cn) : 1.0;
    visit(cn, ke, scale);
  }
}

}  // namespace

namespace {

// Calls entry(row, col, value) for every nonzero entry of every element matrix: cell by cell,
// and within a cell row-major over the element's dofs.
template <class Entry>
void for_each_stiffness_entry(const SubdomainMesh& mesh, const Physics& ph, Entry&& entry) {
  const int nc = cell_nodes(mesh.type), dpn = ph.dofs_per_node();
  for_each_element_matrix(mesh, ph, [&](const int* cn, const Eigen::MatrixXd& ke, double scale) {
    for (int a = 0; a < nc; ++a)
      for (int i = 0; i < dpn; ++i)
        for (int b = 0; b < nc; ++b)
          for (int j = 0; j < dpn; ++j) {
            const double v = scale * ke(a * dpn + i, b * dpn + j);
            if (v != 0.0) entry(cn[a] * dpn + i, cn[b] * dpn + j, v);
          }
  });
}

// Appends the element matrices' nonzero entries to `trip`, cell by cell.
void append_stiffness_triplets(const SubdomainMesh& mesh, const Physics& ph,
                               std::vector<Eigen::Triplet<double>>& trip) {
  for_each_stiffness_entry(mesh, ph,
                           [&](int row, int col, double v) { trip.emplace_back(row, col, v); });
}

// assemble_stiffness's work arrays, kept per thread from one subdomain to the next: fresh pages
// for every subdomain cost more kernel time than the assembly itself on a VM where page faults
// are expensive (docs/performance.md, "Fresh pages").
struct StiffnessWork {
  std::vector<int> start;  // per column: where its contributions begin in row/value
  std::vector<int> count;  // per column: its distinct rows, once summed
  std::vector<int> row;
  std::vector<double> value;
  std::vector<std::pair<int, double>> pairs;  // a long column's distinct rows, sorted
  std::vector<int> slot;                      // per row: its place in the column, or -1
  // Kept only up to this many bytes (large 3D subdomains: freed after each assembly).
  static constexpr size_t kKeepBytes = size_t{32} << 20;
  void trim() {
    const size_t bytes = start.capacity() * sizeof(int) + row.capacity() * sizeof(int) +
                         value.capacity() * sizeof(double) + count.capacity() * sizeof(int) +
                         pairs.capacity() * sizeof(pairs[0]) + slot.capacity() * sizeof(int);
    if (bytes > kKeepBytes) *this = StiffnessWork();
  }
};
thread_local StiffnessWork stiffness_work;

}  // namespace

std::vector<Eigen::Triplet<double>> stiffness_triplets(const SubdomainMesh& mesh,
                                                       const Physics& ph) {
  std::vector<Eigen::Triplet<double>> trip;
  append_stiffness_triplets(mesh, ph, trip);
  return trip;
}

Eigen::SparseMatrix<double> assemble_stiffness(const SubdomainMesh& mesh, const Physics& ph) {
  const int n = mesh.num_nodes() * ph.dofs_per_node();
  StiffnessWork& w = stiffness_work;
  // The contributions grouped by column, in cell order within each, written straight into place
  // (no list of triplets: a third of the memory): every cell holding a column's node reserves
  // nc x dpn places in it; the element matrices' nonzero entries fill them in cell order.
  const int nc = cell_nodes(mesh.type), dpn = ph.dofs_per_node(), ed = nc * dpn;
  w.start.assign(static_cast<size_t>(n) + 1, 0);
  for (int e = 0; e < mesh.num_cells(); ++e)
    for (int b = 0; b < nc; ++b)
      for (int j = 0; j < dpn; ++j)
        w.start[mesh.cells[static_cast<size_t>(e) * nc + b] * dpn + j + 1] += ed;
  for (int c = 0; c < n; ++c) w.start[c + 1] += w.start[c];
  const size_t nt = static_cast<size_t>(w.start[n]);
  w.row.resize(nt);
  w.value.resize(nt);
  w.slot.assign(static_cast<size_t>(n), -1);
  std::vector<int>& fill = w.count;  // per column: its contributions so far
  fill.assign(static_cast<size_t>(n), 0);
  for_each_stiffness_entry(mesh, ph, [&](int row, int col, double v) {
    const int at = w.start[col] + fill[col]++;
    w.row[at] = row, w.value[at] = v;
  });
  // Each column: the contributions to equal rows summed left to right in cell order,
  // ((v1 + v2) + v3) ..., the order of setFromTriplets, then its distinct rows sorted.
  long nnz = 0;
  std::vector<int>& count = w.count;  // (fill[c] read before count[c] is set)
  for (int c = 0; c < n; ++c) {
    int* r = w.row.data() + w.start[c];
    double* v = w.value.data() + w.start[c];
    const int len = fill[c];
    // Equal rows summed in cell order through a slot per distinct row (w.slot, -1 elsewhere),
    // compacted in place: the sums of a stable sort by row followed by a left-to-right sum,
    // without sorting the contributions (up to 8 x 24 per column in 3D elasticity).
    int unique = 0;
    for (int k = 0; k < len; ++k) {
      int& at = w.slot[r[k]];
      if (at < 0) {
        at = unique;
        r[unique] = r[k], v[unique] = v[k];
        ++unique;
      } else {
        v[at] += v[k];
      }
    }
    for (int k = 0; k < unique; ++k) w.slot[r[k]] = -1;
    // Then the distinct rows in order.
    if (unique <= 64) {
      for (int k = 1; k < unique; ++k) {  // insertion sort
        const int rk = r[k];
        const double vk = v[k];
        int q = k;
        for (; q > 0 && r[q - 1] > rk; --q) r[q] = r[q - 1], v[q] = v[q - 1];
        r[q] = rk, v[q] = vk;
      }
    } else {
      w.pairs.resize(static_cast<size_t>(unique));
      for (int k = 0; k < unique; ++k) w.pairs[k] = {r[k], v[k]};
      std::sort(w.pairs.begin(), w.pairs.end(),
                [](const auto& x, const auto& y) { return x.first < y.first; });
      for (int k = 0; k < unique; ++k) r[k] = w.pairs[k].first, v[k] = w.pairs[k].second;
    }
    count[c] = unique;
    nnz += unique;
  }
  Eigen::SparseMatrix<double> K;
  resize_resident(K, n, n, nnz);  // (parallel/fresh_pages.hpp)
  int* outer = K.outerIndexPtr();
  int* inner = K.innerIndexPtr();
  double* value = K.valuePtr();
  long k = 0;
  outer[0] = 0;
  for (int c = 0; c < n; ++c) {
    std::copy_n(w.row.data() + w.start[c], count[c], inner + k);
    std::copy_n(w.value.data() + w.start[c], count[c], value + k);
    k += count[c];
    outer[c + 1] = static_cast<int>(k);
  }
  w.trim();
  return K;
}

double stiffness_form(const SubdomainMesh& mesh, const Physics& ph, const Eigen::VectorXd& u) {
  const int nc = cell_nodes(mesh.type), dpn = ph.dofs_per_node(), ed = nc * dpn;
  if (u.size() != static_cast<Eigen::Index>(mesh.num_nodes()) * dpn)
    throw std::invalid_argument("stiffness_form: u has the wrong size");
  Eigen::VectorXd ue(ed);
  double sum = 0;
  for_each_element_matrix(mesh, ph, [&](const int* cn, const Eigen::MatrixXd& ke, double scale) {
    for (int a = 0; a < nc; ++a)
      for (int i = 0; i < dpn; ++i) ue[a * dpn + i] = u[cn[a] * dpn + i];
    sum += scale * ue.dot(ke * ue);
  });
  return sum;
}

AssembledSubdomain assemble_subdomain(const SubdomainMesh& mesh, const Physics& ph,
                                      const SourceFunction& source) {
  AssembledSubdomain out;
  const int nc = cell_nodes(mesh.type), dpn = ph.dofs_per_node(), ne = mesh.num_cells();
  const int nn = mesh.num_nodes();
  assemble_stiffness(mesh, ph).swap(out.K);
  out.f = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(nn) * dpn);
  if (!ph.coefficient.empty() && ne > 0) {
    const Expression field(ph.coefficient);
    double lo = std::numeric_limits<double>::infinity(), hi = 0;
    for (int e = 0; e < ne; ++e) {
      const double c = cell_coefficient(field, mesh.type, mesh.coords,
                                        mesh.cells.data() + static_cast<size_t>(e) * nc);
      lo = std::min(lo, c), hi = std::max(hi, c);
    }
    out.coefficient_min = lo, out.coefficient_max = hi;
  }
  double x[24];
  const int period = mesh.uniform_period;
  std::vector<double> measures(period > 0 ? std::min(period, ne) : 0);
  for (int e = 0; e < ne; ++e) {
    const int* cn = mesh.cells.data() + static_cast<size_t>(e) * nc;
    for (int a = 0; a < nc; ++a)
      for (int d = 0; d < 3; ++d) x[3 * a + d] = mesh.coords[3 * static_cast<size_t>(cn[a]) + d];
    if (period > 0 && e < period) measures[e] = cell_measure(mesh.type, x);
    const double measure = period > 0 ? measures[e % period] : cell_measure(mesh.type, x);
    if (ph.kind == PhysicsKind::laplace) {
      if (!source) continue;
      const double share = source(cell_centroid(mesh.type, x)) * measure / nc;
      for (int a = 0; a < nc; ++a) out.f[cn[a]] += share;
    } else if (ph.density != 0) {
      for (int a = 0; a < nc; ++a)
        for (int d = 0; d < dpn; ++d)
          out.f[cn[a] * dpn + d] += ph.density * ph.gravity[d] * measure / nc;
    }
  }

  // Connected parts (through shared cells), numbered by their lowest node.
  const std::vector<int> component = node_components(mesh.cells, nc, nn);
  std::vector<int> part_of(nn), root_part(nn, -1);
  int parts = 0;
  for (int k = 0; k < nn; ++k) {
    const int r = component[k];
    if (root_part[r] < 0) root_part[r] = parts++;
    part_of[k] = root_part[r];
  }
  out.parts = parts;
  const int kd = ph.kernel_dimension();
  // The geometry the kernel and the fixed dofs are computed on: on a generated grid the nodes'
  // offsets from node 0 in whole grid spacings (as the element matrices), so that equal
  // subdomains get the same kernel and fixed dofs, not ones that depend on how their
  // coordinates round (ties between equally distant nodes); else the coordinates.
  std::vector<double> geo(mesh.coords.begin(), mesh.coords.end());
  if (nn > 0) grid_offsets(mesh, geo.data(), nn, mesh.coords.data());
  out.R = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(nn) * dpn,
                                static_cast<Eigen::Index>(parts) * kd);
  for (int p = 0; p < parts; ++p) {
    std::vector<int> nodes;
    for (int k = 0; k < nn; ++k)
      if (part_of[k] == p) nodes.push_back(k);
    const int pn = static_cast<int>(nodes.size());
    std::vector<double> xyz(3 * static_cast<size_t>(pn));
    double c[3] = {0, 0, 0};
    for (int i = 0; i < pn; ++i)
      for (int d = 0; d < 3; ++d) {
        xyz[3 * i + d] = geo[3 * static_cast<size_t>(nodes[i]) + d];
        c[d] += xyz[3 * i + d] / pn;
      }
    Eigen::MatrixXd Rp;
    if (ph.kind == PhysicsKind::laplace) {
      Rp = Eigen::MatrixXd::Constant(pn, 1, 1.0 / std::sqrt(static_cast<double>(pn)));
    } else {
      Rp = orthonormal_columns(physics_kernel(ph, xyz.data(), pn));
      if (Rp.cols() != kd)
        throw std::invalid_argument("subdomain " + std::to_string(mesh.id) +
                                    " has a part whose nodes are collinear; its rigid body "
                                    "motions are degenerate");
    }
    for (int i = 0; i < pn; ++i)
      for (int d = 0; d < dpn; ++d)
        out.R.row(static_cast<Eigen::Index>(nodes[i]) * dpn + d).segment(p * kd, kd) =
            Rp.row(static_cast<Eigen::Index>(i) * dpn + d);

    // Fixed dofs. Laplace: the node nearest the part's centroid (lowest index on ties).
    // Elasticity: candidate nodes = nearest to the centroid, then repeatedly the node farthest
    // from the candidates so far (well separated); the dofs are the first kd pivots of a
    // column-pivoted QR of R restricted to the candidates' dofs.
    auto dist2 = [&](int k, const double* q) {
      double s = 0;
      for (int d = 0; d < 3; ++d) {
        const double t = geo[3 * static_cast<size_t>(k) + d] - q[d];
        s += t * t;
      }
      return s;
    };
    int centre = nodes[0];
    double best = dist2(centre, c);
    for (int k : nodes) {
      const double d2 = dist2(k, c);
      if (d2 < best - 1e-12 * best) best = d2, centre = k;
    }
    if (ph.kind == PhysicsKind::laplace) {
      out.fixed_dofs.push_back(centre);
      continue;
    }
    std::vector<int> cand{centre};
    std::vector<double> mind(pn, 0.0);
    for (int i = 0; i < pn; ++i) mind[i] = dist2(nodes[i], &geo[3 * static_cast<size_t>(centre)]);
    const int ncand = std::min(pn, mesh.dim == 2 ? 3 : 4);
    while (static_cast<int>(cand.size()) < ncand) {
      int far = 0;
      for (int i = 1; i < pn; ++i)
        if (mind[i] > mind[far]) far = i;
      if (mind[far] == 0) break;
      cand.push_back(nodes[far]);
      for (int i = 0; i < pn; ++i)
        mind[i] = std::min(mind[i], dist2(nodes[i], &geo[3 * static_cast<size_t>(nodes[far])]));
    }
    Eigen::MatrixXd Rc(static_cast<Eigen::Index>(cand.size()) * dpn, kd);
    std::vector<int> dofs;
    for (size_t i = 0; i < cand.size(); ++i)
      for (int d = 0; d < dpn; ++d) {
        Rc.row(static_cast<Eigen::Index>(i) * dpn + d) =
            out.R.row(static_cast<Eigen::Index>(cand[i]) * dpn + d).segment(p * kd, kd);
        dofs.push_back(cand[i] * dpn + d);
      }
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Rc.transpose());
    if (qr.rank() < kd)
      throw std::invalid_argument("subdomain " + std::to_string(mesh.id) +
                                  ": no set of dofs removes its rigid body motions");
    std::vector<int> chosen;
    for (int i = 0; i < kd; ++i) chosen.push_back(dofs[qr.colsPermutation().indices()[i]]);
    std::sort(chosen.begin(), chosen.end());
    out.fixed_dofs.insert(out.fixed_dofs.end(), chosen.begin(), chosen.end());
  }
  std::sort(out.fixed_dofs.begin(), out.fixed_dofs.end());
  return out;
}

void add_facet_shares(const SubdomainMesh& mesh, const SubdomainMesh::FacetGroup& g,
                      std::vector<double>& share_of_node) {
  const int fn = g.facet_nodes;
  if (fn == 0) return;
  double x[12] = {};
  for (size_t i = 0; i + fn <= g.nodes.size(); i += fn) {
    for (int a = 0; a < fn; ++a)
      for (int d = 0; d < 3; ++d)
        x[3 * a + d] = mesh.coords[3 * static_cast<size_t>(g.nodes[i + a]) + d];
    const double share = facet_measure(mesh.dim, fn, x) / fn;
    for (int a = 0; a < fn; ++a) share_of_node[g.nodes[i + a]] += share;
  }
}

void add_traction(const SubdomainMesh& mesh, const SubdomainMesh::FacetGroup& g, const Physics& ph,
                  const std::array<double, 3>& t, Eigen::VectorXd& f) {
  const int fn = g.facet_nodes, dpn = ph.dofs_per_node();
  if (fn == 0) return;
  double x[12];
  for (size_t i = 0; i + fn <= g.nodes.size(); i += fn) {
    for (int a = 0; a < fn; ++a)
      for (int d = 0; d < 3; ++d)
        x[3 * a + d] = mesh.coords[3 * static_cast<size_t>(g.nodes[i + a]) + d];
    const double share = facet_measure(mesh.dim, fn, x) / fn;
    for (int a = 0; a < fn; ++a)
      for (int d = 0; d < dpn; ++d)
        f[static_cast<Eigen::Index>(g.nodes[i + a]) * dpn + d] += t[d] * share;
  }
}

}  // namespace htfeti
