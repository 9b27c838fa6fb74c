#include "htfeti/feti/constraints.hpp"

#include "htfeti/linalg/orthonormal.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

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

// Orthonormal kernel W on the object's dofs and an orthonormal basis of its complement.
void object_bases(const FetiLayout& L, const DofSharing& sh, const std::vector<int>& nodes,
                  Eigen::MatrixXd& W, Eigen::MatrixXd& Wc) {
  const int p = static_cast<int>(nodes.size()), dpn = L.dofs_per_node;
  std::vector<double> xyz(3 * static_cast<size_t>(p));
  for (int t = 0; t < p; ++t)
    for (int d = 0; d < 3; ++d) xyz[3 * t + d] = sh.coords[3 * static_cast<size_t>(nodes[t]) + d];
  const Eigen::MatrixXd A = L.kernel(xyz.data(), p);
  if (A.cols() == 1 && (A.array() == A(0, 0)).all()) {
    // Constants: the Helmert complement (sparse-structured, as for the paper's edge rows).
    W = Eigen::MatrixXd::Constant(p * dpn, 1, 1.0 / std::sqrt(static_cast<double>(p * dpn)));
    const auto rows = orthonormal_complement(std::vector<double>(p * dpn, 1.0));
    Wc.resize(p * dpn, static_cast<int>(rows.size()));
    for (size_t j = 0; j < rows.size(); ++j)
      for (int i = 0; i < p * dpn; ++i) Wc(i, static_cast<int>(j)) = rows[j][i];
    return;
  }
  // Rank-revealing orthonormalization, then the complement from a full QR.
  W = orthonormal_columns(A);
  const int r = static_cast<int>(W.cols());
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(W);
  const Eigen::MatrixXd full = qr.householderQ() * Eigen::MatrixXd::Identity(W.rows(), W.rows());
  Wc = full.rightCols(W.rows() - r);
}

}  // namespace

void subdomain_rows(const FetiLayout& L, const SubdomainInput& in, std::vector<LocalRow>& out) {
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
  // 3. contact rows.
  for (const auto& c : in.contact) {
    const double inv = 1.0 / c.copies_a + (c.copies_b > 0 ? 1.0 / c.copies_b : 0.0);
    const double scale = 1.0 / std::sqrt(inv);
    row = LocalRow{};
    row.key = {0, c.node_a, 2, 0, 0, 0};
    row.kind = MultiplierKind::contact;
    row.owner_subdomain = c.owner_subdomain;
    row.rhs = scale * c.gap;
    row.scale = scale;
    row.gap = c.gap;
    row.point = c.point;
    row.direction = c.direction;
    row.side = c.side;
    const double w = c.side > 0 ? scale / c.copies_a : -scale / c.copies_b;
    for (int i = 0; i < dpn; ++i)
      if (c.direction[i] != 0.0) row.entries.push_back({c.node * dpn + i, w * c.direction[i]});
    out.push_back(std::move(row));
  }
  // 4. rows of averaged objects.
  const double r2 = 1.0 / std::sqrt(2.0);
  Eigen::MatrixXd W, Wc;
  for (const auto& [pair, nodes] : averaged_objects(sh, cls)) {
    object_bases(L, sh, nodes, W, Wc);
    // Sign: + on the first copy in the canonical order.
    const int* cp = sh.copies(nodes[0]);
    const double sign = cp[0] == me ? 1.0 : -1.0;
    long long min_node = sh.global_node[nodes[0]];
    for (int l = 0; l < Wc.cols(); ++l) {
      row = LocalRow{};
      row.key = {1, my_cluster, pair.second - pair.first, pair.first, min_node, l};
      row.kind = MultiplierKind::gluing;
      row.owner_subdomain = pair.first;
      for (size_t t = 0; t < nodes.size(); ++t)
        for (int i = 0; i < dpn; ++i) {
          const double v = Wc(static_cast<int>(t) * dpn + i, l);
          if (v != 0.0) row.entries.push_back({nodes[t] * dpn + i, sign * v * r2});
        }
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
  Eigen::MatrixXd W, Wc;
  for (size_t mi = 0; mi < members.size(); ++mi) {
    const SubdomainInput& in = *members[mi];
    const DofSharing& sh = in.sharing;
    const int me = in.system.id;
    if (me - first != static_cast<int>(mi)) throw std::logic_error("cluster members out of order");
    const Classes cls = classify(L, sh, cluster);
    if (averages)
      for (const auto& [pair, nodes] : averaged_objects(sh, cls)) {
        object_bases(L, sh, nodes, W, Wc);
        const double sign = sh.copies(nodes[0])[0] == me ? 1.0 : -1.0;
        for (int l = 0; l < W.cols(); ++l) {
          auto& r = keyed[{0, pair.second - pair.first, pair.first, sh.global_node[nodes[0]], l, 0}];
          for (size_t t = 0; t < nodes.size(); ++t)
            for (int i = 0; i < dpn; ++i) {
              const double v = W(static_cast<int>(t) * dpn + i, l);
              if (v != 0.0)
                r.push_back({static_cast<int>(mi), nodes[t] * dpn + i, sign * v * r2});
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
