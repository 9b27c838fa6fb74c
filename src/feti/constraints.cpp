#include "htfeti/feti/constraints.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <numeric>
#include <stdexcept>

#include "htfeti/linalg/orthonormal.hpp"

namespace htfeti {

std::vector<std::vector<double>> orthonormal_complement(const std::vector<double>& s) {
  // Generalized Helmert basis: row j = (s_1, ..., s_j, -(s_1^2 + ... + s_j^2) / s_{j+1}, 0, ...).
  const int t = static_cast<int>(s.size());
  std::vector<std::vector<double>> rows;
  double sum_sq = 0;
  for (int j = 1; j < t; ++j) {
    sum_sq += s[j - 1] * s[j - 1];
    std::vector<double> r(t, 0.0);
    for (int i = 0; i < j; ++i) r[i] = s[i];
    r[j] = -sum_sq / s[j];
    double norm = 0;
    for (double v : r) norm += v * v;
    norm = std::sqrt(norm);
    for (double& v : r) v /= norm;
    rows.push_back(std::move(r));
  }
  return rows;
}

namespace {

// Interface classification of the nodes of one subdomain (see the header).
struct Classes {
  std::vector<char> averaged, vertex;
};

Classes classify(const FetiLayout& L, const DofSharing& sh, int my_cluster) {
  const int nn = sh.num_nodes();
  Classes c;
  c.averaged.assign(nn, 0);
  c.vertex.assign(nn, 0);
  const bool averages = L.glue != Glue::corners && L.cluster_size(my_cluster) > 1;
  std::map<std::vector<int>, int> count;
  std::vector<std::vector<int>> ext(nn);
  for (int k = 0; k < nn; ++k) {
    const int kc = sh.num_copies(k);
    if (kc < 2) continue;
    const int* cp = sh.copies(k);
    if (averages && kc == 2 && !sh.on_boundary[k] && L.cluster_of(cp[0]) == my_cluster &&
        L.cluster_of(cp[1]) == my_cluster)
      c.averaged[k] = 1;
    if (kc + (sh.on_boundary[k] ? 1 : 0) >= 3) {
      ext[k].assign(cp, cp + kc);
      std::sort(ext[k].begin(), ext[k].end());
      if (sh.on_boundary[k]) ext[k].push_back(-1);
      ++count[ext[k]];
    }
  }
  for (int k = 0; k < nn; ++k)
    if (!ext[k].empty()) c.vertex[k] = L.dim == 2 || count[ext[k]] == 1;
  return c;
}

// Averaged objects of a subdomain: pair (lower, higher subdomain id) -> nodes by global id.
std::map<std::pair<int, int>, std::vector<int>> averaged_objects(const DofSharing& sh,
                                                                 const Classes& cls) {
  std::map<std::pair<int, int>, std::vector<int>> obj;
  for (int k = 0; k < sh.num_nodes(); ++k)
    if (cls.averaged[k]) {
      const int* cp = sh.copies(k);
      obj[{std::min(cp[0], cp[1]), std::max(cp[0], cp[1])}].push_back(k);
    }
  for (auto& [pair, nodes] : obj)
    std::sort(nodes.begin(), nodes.end(),
              [&](int a, int b) { return sh.global_node[a] < sh.global_node[b]; });
  return obj;
}

// Orthonormal kernel W of the physics on the object's dofs; xyz gets the nodes' coordinates.
// The kernel is taken in the model's frame for it (DofSharing::kernel_frame: on a generated grid
// the offsets from the object's first node in whole grid spacings, the same span: rigid motions
// about another point), so that equal objects at different places give the same W bit for bit,
// and equal subdomains the same C_i (their K_i^+ C_i^T are then computed and held once,
// SparseCholesky::shared_result).
Eigen::MatrixXd object_kernel(const FetiLayout& L, const DofSharing& sh,
                              const std::vector<int>& nodes, std::vector<double>& xyz) {
  const int p = static_cast<int>(nodes.size());
  xyz.resize(3 * static_cast<size_t>(p));
  for (int t = 0; t < p; ++t)
    for (int d = 0; d < 3; ++d) xyz[3 * t + d] = sh.coords[3 * static_cast<size_t>(nodes[t]) + d];
  if (!sh.kernel_frame || p == 0) return orthonormal_columns(L.kernel(xyz.data(), p));
  std::vector<double> frame(xyz);
  sh.kernel_frame(frame.data(), p);
  return orthonormal_columns(L.kernel(frame.data(), p));  // rank-revealing
}

// hierarchical_complement in two steps: the tree of the nodes from their coordinates (its leaf
// order), then the rows from W and that order. The rows depend on the coordinates only through
// the leaf order, so objects with the same W and the same order (the faces of a box) can share
// them (ObjectRowCache).
constexpr int kLeafNodes = 4;

// The leaf order of the group `idx` (node indices), appended to `order`: the group is bisected
// along the axis of largest extent (ties: the first such axis; equal coordinates keep their
// order), the lower half first, down to leaves of at most kLeafNodes nodes.
void leaf_order(const double* xyz, std::vector<int> idx, std::vector<int>& order) {
  const int g = static_cast<int>(idx.size());
  if (g <= kLeafNodes) {
    order.insert(order.end(), idx.begin(), idx.end());
    return;
  }
  int axis = 0;
  double best = -1;
  for (int d = 0; d < 3; ++d) {
    double lo = xyz[3 * idx[0] + d], hi = lo;
    for (int t : idx) lo = std::min(lo, xyz[3 * t + d]), hi = std::max(hi, xyz[3 * t + d]);
    if (hi - lo > best) best = hi - lo, axis = d;
  }
  std::stable_sort(idx.begin(), idx.end(),
                   [&](int a, int b) { return xyz[3 * a + axis] < xyz[3 * b + axis]; });
  leaf_order(xyz, std::vector<int>(idx.begin(), idx.begin() + g / 2), order);
  leaf_order(xyz, std::vector<int>(idx.begin() + g / 2, idx.end()), order);
}

std::vector<int> leaf_order(const double* xyz, int p) {
  std::vector<int> idx(p), order;
  std::iota(idx.begin(), idx.end(), 0);
  order.reserve(p);
  leaf_order(xyz, std::move(idx), order);
  return order;
}

// The group order[lo, hi) of the tree (split in the middle, as leaf_order splits). Returns the
// group's coarse basis E (orthonormal columns spanning W restricted to the group, rows = the
// group's dofs in the order of `dofs`) and appends the group's detail rows after its children's.
void complement_group(const Eigen::MatrixXd& W, int dpn, const std::vector<int>& order, int lo,
                      int hi, std::vector<int>& dofs, Eigen::MatrixXd& E, SparseRows& details) {
  const int g = hi - lo;
  Eigen::MatrixXd basis;  // columns spanning the group's part of W (rows: dofs)
  if (g <= kLeafNodes) {
    dofs.clear();
    for (int q = lo; q < hi; ++q)
      for (int i = 0; i < dpn; ++i) dofs.push_back(order[q] * dpn + i);
    basis = Eigen::MatrixXd::Identity(static_cast<int>(dofs.size()), static_cast<int>(dofs.size()));
  } else {
    std::vector<int> d1, d2;
    Eigen::MatrixXd E1, E2;
    complement_group(W, dpn, order, lo, lo + g / 2, d1, E1, details);
    complement_group(W, dpn, order, lo + g / 2, hi, d2, E2, details);
    dofs = d1;
    dofs.insert(dofs.end(), d2.begin(), d2.end());
    basis = Eigen::MatrixXd::Zero(static_cast<int>(dofs.size()), E1.cols() + E2.cols());
    basis.topLeftCorner(E1.rows(), E1.cols()) = E1;
    basis.bottomRightCorner(E2.rows(), E2.cols()) = E2;
  }
  // W restricted to the group, in the coordinates of `basis` (orthonormal columns).
  Eigen::MatrixXd Wg(static_cast<int>(dofs.size()), W.cols());
  for (size_t r = 0; r < dofs.size(); ++r) Wg.row(static_cast<int>(r)) = W.row(dofs[r]);
  const Eigen::MatrixXd A = basis.transpose() * Wg;
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullU);
  const auto& sv = svd.singularValues();
  int rank = 0;  // W has orthonormal columns: singular values are at most 1
  while (rank < sv.size() && sv[rank] > 1e-12) ++rank;
  const Eigen::MatrixXd U = basis * svd.matrixU();
  E = U.leftCols(rank);
  for (int j = rank; j < U.cols(); ++j) {
    std::vector<std::pair<int, double>> row;
    for (int r = 0; r < U.rows(); ++r)
      if (U(r, j) != 0.0) row.push_back({dofs[r], U(r, j)});
    details.push_back(std::move(row));
  }
}

SparseRows complement_rows(const Eigen::MatrixXd& W, const std::vector<int>& order, int dpn) {
  SparseRows rows;
  std::vector<int> dofs;
  Eigen::MatrixXd E;
  complement_group(W, dpn, order, 0, static_cast<int>(order.size()), dofs, E, rows);
  // The top group's coarse basis spans W itself: its complement in the span of the children's
  // coarse bases was emitted as the top group's details, so `rows` holds p*dpn - rank(W) rows.
  return rows;
}

}  // namespace

SparseRows hierarchical_complement(const Eigen::MatrixXd& W, const double* xyz, int p, int dpn) {
  return complement_rows(W, leaf_order(xyz, p), dpn);
}

std::shared_ptr<const SparseRows> ObjectRowCache::rows(const Eigen::MatrixXd& W, const double* xyz,
                                                       int p, int dpn) {
  auto mine = std::make_shared<Entry>();
  mine->order = leaf_order(xyz, p);
  mine->dpn = dpn;
  mine->w_rows = W.rows();
  mine->w.assign(W.data(), W.data() + W.size());
  std::uint64_t h = 1469598103934665603ULL;  // FNV-1a over the bits of W, the order and dpn
  auto mix = [&h](std::uint64_t v) { h = (h ^ v) * 1099511628211ULL; };
  for (double v : mine->w) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    mix(bits);
  }
  for (int t : mine->order) mix(static_cast<std::uint64_t>(t));
  mix(static_cast<std::uint64_t>(dpn));
  mine->hash = h;
  bool owner = false;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    std::shared_ptr<Entry> found;
    for (const auto& e : entries_)
      if (e->hash == h && e->dpn == dpn && e->w_rows == mine->w_rows && e->w == mine->w &&
          e->order == mine->order) {
        found = e;
        break;
      }
    if (found) {
      ready_.wait(lock, [&] { return found->rows != nullptr || found->failed; });
      if (!found->failed) {
        ++reuses_;
        return found->rows;
      }
    } else {
      entries_.push_back(mine);  // rows still null: equal keys wait for them
      owner = true;
    }
  }
  // The first holder of an equal key failed: computed unshared.
  if (!owner) return std::make_shared<const SparseRows>(complement_rows(W, mine->order, dpn));
  std::shared_ptr<const SparseRows> out;
  try {
    out = std::make_shared<const SparseRows>(complement_rows(W, mine->order, dpn));
  } catch (...) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      mine->failed = true;
    }
    ready_.notify_all();
    throw;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    mine->rows = out;
  }
  ready_.notify_all();
  return out;
}

void subdomain_rows(const FetiLayout& L, const SubdomainInput& in, std::vector<LocalRow>& out,
                    ObjectRowCache* cache) {
  const DofSharing& sh = in.sharing;
  const int me = in.system.id, my_cluster = L.cluster_of(me), dpn = L.dofs_per_node;
  const int nn = sh.num_nodes();
  const Classes cls = classify(L, sh, my_cluster);
  const bool corners = L.glue != Glue::averages;

  LocalRow row;
  std::vector<int> group, sizes;
  std::vector<double> s;
  // 1. per-node gluing rows.
  for (int k = 0; k < nn; ++k) {
    const int kc = sh.num_copies(k);
    if (kc < 2 || cls.averaged[k]) continue;
    const int* cp = sh.copies(k);
    // Groups: copies of one cluster are joined primally at a vertex with corner gluing.
    group.assign(kc, -1);
    sizes.clear();
    int mine = -1;
    for (int i = 0; i < kc; ++i) {
      const int ci = L.cluster_of(cp[i]);
      if (corners && cls.vertex[k] && L.cluster_size(ci) > 1)
        for (int j = 0; j < i; ++j)
          if (L.cluster_of(cp[j]) == ci) {
            group[i] = group[j];
            break;
          }
      if (group[i] < 0) {
        group[i] = static_cast<int>(sizes.size());
        sizes.push_back(0);
      }
      ++sizes[group[i]];
      if (cp[i] == me) mine = i;
    }
    if (mine < 0) throw std::logic_error("a node's copies do not list its own subdomain");
    if (sizes.size() < 2) continue;
    s.resize(sizes.size());
    for (size_t g = 0; g < sizes.size(); ++g) s[g] = std::sqrt(static_cast<double>(sizes[g]));
    const int owner = *std::min_element(cp, cp + kc);
    const auto basis = orthonormal_complement(s);
    const int g = group[mine];
    for (size_t j = 0; j < basis.size(); ++j)
      for (int i = 0; i < dpn; ++i) {
        row = LocalRow{};
        row.key = {0, sh.global_node[k], 0, static_cast<long long>(j) * dpn + i, 0, 0};
        row.kind = MultiplierKind::gluing;
        row.owner_subdomain = owner;
        row.entries.push_back({k * dpn + i, basis[j][g] / s[g]});
        out.push_back(std::move(row));
      }
  }
  // 2. Dirichlet rows.
  for (const auto& d : in.dirichlet) {
    const int kc = sh.num_copies(d.node);
    const int* cp = sh.copies(d.node);
    row = LocalRow{};
    row.key = {0, sh.global_node[d.node], 1, d.component, 0, 0};
    row.kind = MultiplierKind::dirichlet;
    row.owner_subdomain = *std::min_element(cp, cp + kc);
    row.rhs = std::sqrt(static_cast<double>(kc)) * d.value;
    row.entries.push_back({d.node * dpn + d.component, 1.0 / std::sqrt(kc * 1.0)});
    out.push_back(std::move(row));
  }
  // 3. contact rows: this subdomain's part of n.(sum_j c_j avg u_j) <= W gap, scaled to unit
  // norm (input.hpp, ContactRow).
  for (const auto& c : in.contact) {
    const double scale = 1.0 / std::sqrt(c.norm_sq);
    row = LocalRow{};
    row.key = {0, c.node_a, 2, c.condition, 0, 0};
    row.kind = MultiplierKind::contact;
    row.owner_subdomain = c.owner_subdomain;
    row.rhs = scale * (c.weight * c.gap);
    row.scale = scale;
    row.weight = c.weight;
    row.gap = c.gap;
    row.area = c.area;
    row.condition = c.condition;
    row.point = c.point;
    row.direction = c.direction;
    row.side = c.side;
    row.key_node = c.key;
    const double w = c.coefficient * scale / c.copies;
    for (int i = 0; i < dpn; ++i)
      if (c.direction[i] != 0.0) row.entries.push_back({c.node * dpn + i, w * c.direction[i]});
    out.push_back(std::move(row));
    if ((c.slip_bound >= 0 || c.friction_coefficient >= 0) && dpn >= 2) {
      // Friction: the tangential rows t.(sum_j c_j avg u_j), t = (-n_y, n_x) in 2D, t1 and
      // t2 = n x t1 in 3D, scaled as the normal row (their force is W scale lambda), with
      // |lambda_t| <= g A / (W scale) summed over the copies of the node (Tresca; A the row's
      // contact area) or mu lambda_n (Coulomb, set between solves). No right-hand side: the
      // tangential displacement is free where the bound is reached (slip), zero below it (stick).
      // In 3D a node that Dirichlet conditions leave one tangential direction has the row
      // along c.tangent alone (key index kSingleTangent: an interval, no disc partner).
      const auto& n = c.direction;
      std::array<std::array<double, 3>, 2> t{};
      t[0] = dpn == 2 ? std::array<double, 3>{-n[1], n[0], 0} : c.tangent;
      t[1] = {n[1] * t[0][2] - n[2] * t[0][1], n[2] * t[0][0] - n[0] * t[0][2],
              n[0] * t[0][1] - n[1] * t[0][0]};
      const bool single = dpn == 3 && c.tangent_rows == 1;
      for (int m = 0; m < (single ? 1 : dpn - 1); ++m) {
        row = LocalRow{};
        row.key = {0, c.node_a, 3, c.condition, single ? kSingleTangent : m, 0};
        row.kind = MultiplierKind::friction;
        row.owner_subdomain = c.owner_subdomain;
        row.scale = scale;
        row.weight = c.weight;
        row.condition = c.condition;
        row.point = c.point;
        row.direction = t[m];
        row.side = c.side;  // the contact force -B_I^T lambda takes it (contact_forces)
        row.key_node = c.key;
        // Coulomb's first solve: unbounded (stick) where the gap is closed at the start, so
        // that it has a solution whenever the normal contact holds the body, also under a
        // tangential load; frictionless (bound 0) where the gap is open, as the fixed point's
        // next bound mu lambda_n = 0 is there unless the gap closes. (Sticking across an open
        // gap would glue the bodies along the tangents of surfaces far apart: on the 3D
        // Cattaneo-Mindlin sphere that first solve took 41,000 CG steps, the rest 7,000.)
        // "Closed": gap <= 1e-8 sqrt(A) (2D: 1e-8 A), the node's contact area A as length scale.
        // (the row's force is W scale lambda: |W scale lambda| <= g A)
        const double closed = 1e-8 * (dpn == 3 ? std::sqrt(c.area) : c.area);
        row.bound = c.slip_bound >= 0 ? c.slip_bound * c.area / (scale * c.weight)
                    : c.gap <= closed ? std::numeric_limits<double>::infinity()
                                      : 0.0;
        row.mu = c.friction_coefficient;
        for (int i = 0; i < dpn; ++i)
          if (row.direction[i] != 0.0)
            row.entries.push_back({c.node * dpn + i, w * row.direction[i]});
        out.push_back(std::move(row));
      }
    }
  }
  // 4. rows of averaged objects.
  const double r2 = 1.0 / std::sqrt(2.0);
  std::vector<double> xyz;
  for (const auto& [pair, nodes] : averaged_objects(sh, cls)) {
    const Eigen::MatrixXd W = object_kernel(L, sh, nodes, xyz);
    const int p = static_cast<int>(nodes.size());
    const std::shared_ptr<const SparseRows> held =
        cache ? cache->rows(W, xyz.data(), p, dpn)
              : std::make_shared<const SparseRows>(hierarchical_complement(W, xyz.data(), p, dpn));
    const SparseRows& Wc = *held;
    // Sign: + on the first copy in the canonical order.
    const int* cp = sh.copies(nodes[0]);
    const double sign = cp[0] == me ? 1.0 : -1.0;
    long long min_node = sh.global_node[nodes[0]];
    for (size_t l = 0; l < Wc.size(); ++l) {
      row = LocalRow{};
      row.key = {1,          my_cluster, pair.second - pair.first,
                 pair.first, min_node,   static_cast<long long>(l)};
      row.kind = MultiplierKind::gluing;
      row.owner_subdomain = pair.first;
      for (const auto& [j, v] : Wc[l])  // j = t * dpn + i: component i of the object's node t
        row.entries.push_back({nodes[j / dpn] * dpn + j % dpn, sign * v * r2});
      out.push_back(std::move(row));
    }
  }
}

std::vector<std::vector<ConstraintEntry>> cluster_primal_constraints(
    const FetiLayout& L, int cluster, const std::vector<const SubdomainInput*>& members) {
  std::vector<std::vector<ConstraintEntry>> rows;
  if (members.size() < 2) return rows;
  const int dpn = L.dofs_per_node, first = L.cluster_first[cluster];
  const bool corners = L.glue != Glue::averages, averages = L.glue != Glue::corners;
  std::map<RowKey, std::vector<ConstraintEntry>> keyed;
  const double r2 = 1.0 / std::sqrt(2.0);
  std::vector<double> xyz;
  for (size_t mi = 0; mi < members.size(); ++mi) {
    const SubdomainInput& in = *members[mi];
    const DofSharing& sh = in.sharing;
    const int me = in.system.id;
    if (me - first != static_cast<int>(mi)) throw std::logic_error("cluster members out of order");
    const Classes cls = classify(L, sh, cluster);
    if (averages)
      for (const auto& [pair, nodes] : averaged_objects(sh, cls)) {
        const Eigen::MatrixXd W = object_kernel(L, sh, nodes, xyz);
        const double sign = sh.copies(nodes[0])[0] == me ? 1.0 : -1.0;
        for (int l = 0; l < W.cols(); ++l) {
          auto& r =
              keyed[{0, pair.second - pair.first, pair.first, sh.global_node[nodes[0]], l, 0}];
          for (size_t t = 0; t < nodes.size(); ++t)
            for (int i = 0; i < dpn; ++i) {
              const double v = W(static_cast<int>(t) * dpn + i, l);
              if (v != 0.0) r.push_back({static_cast<int>(mi), nodes[t] * dpn + i, sign * v * r2});
            }
        }
      }
    if (corners)
      for (int k = 0; k < sh.num_nodes(); ++k) {
        if (!cls.vertex[k]) continue;
        const int kc = sh.num_copies(k);
        const int* cp = sh.copies(k);
        std::vector<int> intra;
        int mine = -1;
        for (int i = 0; i < kc; ++i)
          if (L.cluster_of(cp[i]) == cluster) {
            if (cp[i] == me) mine = static_cast<int>(intra.size());
            intra.push_back(cp[i]);
          }
        if (intra.size() < 2) continue;
        const auto basis = orthonormal_complement(std::vector<double>(intra.size(), 1.0));
        for (size_t j = 0; j < basis.size(); ++j)
          for (int i = 0; i < dpn; ++i)
            keyed[{1, sh.global_node[k], static_cast<long long>(j), i, 0, 0}].push_back(
                {static_cast<int>(mi), k * dpn + i, basis[j][mine]});
      }
  }
  for (auto& [key, entries] : keyed) rows.push_back(std::move(entries));
  return rows;
}

}  // namespace htfeti
