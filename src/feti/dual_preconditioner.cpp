// DualPreconditioner (dual_preconditioner.hpp): its setup stages, the stiffness scaling of B_D,
// and the application M^{-1} x.
#include "htfeti/feti/dual_preconditioner.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "htfeti/feti/dual_problem.hpp"

namespace htfeti {

void DualPreconditioner::start(const FetiOptions& options, const FetiLayout& layout, int nsub) {
  if (options.preconditioner == PreconditionerKind::automatic ||
      options.scaling == Scaling::automatic)
    throw std::logic_error("DualProblem: resolve the automatic preconditioner first");
  kind_ = options.preconditioner;
  scaling_ = options.scaling;
  layers_ = options.dirichlet_layers;
  single_ = options.factor_precision != FactorPrecision::double_;
  dim_ = layout.dim;
  // Exact stiffness scaling on the nodes needs their copy counts. Copies joined primally (corner
  // glue) form groups, for which the identity used there does not hold: those runs weight each
  // per-node row over its own entries instead (build_scaling).
  exact_node_scaling_ = built() && scaling_ == Scaling::stiffness;
  if (exact_node_scaling_) {
    bool groups = false;
    for (int c = 0; c < layout.num_clusters; ++c) groups |= layout.cluster_size(c) > 1;
    exact_node_scaling_ = layout.glue == Glue::averages || !groups;
  }
  if (exact_node_scaling_) node_copies_.resize(nsub);
}

bool DualPreconditioner::implicit_storage(const FetiOptions& options, int dim, bool dense_fits) {
  return options.dirichlet_storage == 2 ||
         (options.dirichlet_storage == 0 && (dim == 3 || !dense_fits));
}

std::vector<std::vector<int>> DualPreconditioner::plan(const FetiOptions& options,
                                                       const Multipliers& m, const Comm& comm) {
  // The preconditioner's interface per subdomain: the dofs its rows of B~ touch (sorted), and
  // per row entry the position of its dof there. Dense Dirichlet blocks when they fit.
  const int nsub = m.subdomains();
  std::vector<std::vector<int>> interface(built() ? nsub : 0);
  if (!built()) return interface;
  double dense_bytes = 0;
  interface_position_.resize(nsub);
  for (int s = 0; s < nsub; ++s) {
    auto& in = interface[s];
    for (const auto& r : m.rows[s]) in.push_back(r.dof);
    std::sort(in.begin(), in.end());
    in.erase(std::unique(in.begin(), in.end()), in.end());
    for (const auto& r : m.rows[s])
      interface_position_[s].push_back(
          static_cast<int>(std::lower_bound(in.begin(), in.end(), r.dof) - in.begin()));
    dense_bytes += 8.0 * in.size() * in.size();
  }
  // Automatic storage (bench/dirichlet_storage.py, docs/performance.md "The Dirichlet
  // preconditioner's storage"): in 2D a part's interface is a curve, n_b is small beside its
  // interior and the dense S_i is both smaller than the factor of K_ii and applied several times
  // faster; in 3D the interface is a surface, 8 n_b^2 bytes exceed that factor (3 to 7 times on
  // the measured parts) and forming S_i from n_b right-hand sides costs 15 to 35 times the
  // implicit setup, so 3D takes the implicit storage whatever the budget.
  const bool fits = comm.max(dense_bytes) <= options.dirichlet_dense_budget_bytes;
  if (kind_ == PreconditionerKind::dirichlet && options.dirichlet_storage == 0 && dim_ == 2 &&
      !fits && options.dirichlet_fallback != PreconditionerKind::dirichlet) {
    kind_ = options.dirichlet_fallback;
    if (!built()) {
      interface.clear(), interface_position_.clear();
      exact_node_scaling_ = false;
      node_copies_ = {};
    }
  }
  dense_ = kind_ == PreconditionerKind::dirichlet && !implicit_storage(options, dim_, fits);
  if (built()) local_.resize(nsub);
  return interface;
}

void DualPreconditioner::set_up_subdomain(int s, const Eigen::SparseMatrix<double>& K,
                                          std::vector<int> interface, Ordering ordering,
                                          const Eigen::MatrixXd* kernel, SubdomainCache* cache) {
  local_[s] = std::make_unique<LocalPreconditioner>(K, std::move(interface), kind_, dense_,
                                                    ordering, kernel, cache, layers_, single_);
}

void DualPreconditioner::finish(Multipliers& m, const std::vector<std::vector<double>>& rho,
                                const std::vector<int>& dofs_per_node) {
  if (!built()) return;
  const int nsub = m.subdomains();
  in_.resize(nsub), out_.resize(nsub);
  for (int s = 0; s < nsub; ++s)
    in_[s] = Vec::Zero(local_[s]->size()), out_[s] = Vec::Zero(local_[s]->size());
  if (scaling_ == Scaling::stiffness) build_scaling(m, rho, dofs_per_node);
}

void DualPreconditioner::build_scaling(Multipliers& m, const std::vector<std::vector<double>>& rho,
                                       const std::vector<int>& dofs_per_node) {
  // Per (subdomain s, row r): rho_{r,s}, the b^2-weighted mean of diag K_s over the row's
  // entries on s; summed over the subdomains of each row: W_r = sum_s rho_{r,s} and, for
  // per-node rows (one entry b_{r,s} per subdomain), V_r = sum_s rho_{r,s} b_{r,s}. With the
  // weights delta_s = rho_{r,s} / W_r the scaled entries are
  //   per-node rows: b - sum_s delta_s b_{r,s}, so that B_D^T B~ on a node with copies
  //     weighted by delta is the jump operator u_s - sum_t delta_t u_t (for uniform weights
  //     the sum vanishes: B_D = B~);
  //   averaged-object rows (w, -w)/sqrt(2) on two subdomains: 2 (1 - delta_s) b, the weight of
  //     the other side (again B_D = B~ for uniform weights);
  //   Dirichlet and contact rows: b.
  const int nsub = m.subdomains(), n_own = m.layout.n_owned();
  const int npairs = static_cast<int>(m.pairs.size());
  Vec num = Vec::Zero(npairs), den = Vec::Zero(npairs), bpair = Vec::Zero(npairs);
  for (int s = 0; s < nsub; ++s)
    for (size_t e = 0; e < m.rows[s].size(); ++e) {
      const BRowEntry& r = m.rows[s][e];
      const int p = m.pair_first[s] + r.j;
      num[p] += r.value * r.value * rho[s][e];
      den[p] += r.value * r.value;
      if (r.cls == RowClass::node) bpair[p] = r.value;
    }
  const Vec rs = (den.array() > 0).select(num.cwiseQuotient(den.cwiseMax(1e-300)), 0.0);
  {  // per row: sum_s b^2 / sum_s (b^2 / rho): the harmonic mean of the copies' stiffness
    Vec inv = Vec::Zero(npairs);
    for (int s = 0; s < nsub; ++s)
      for (size_t e = 0; e < m.rows[s].size(); ++e) {
        const BRowEntry& r = m.rows[s][e];
        if (rho[s][e] > 0) inv[m.pair_first[s] + r.j] += r.value * r.value / rho[s][e];
      }
    m.pairs = inv;
    m.combine_subdomains();
    const Vec a = m.ext_out.head(n_own);
    m.pairs = den;
    m.combine_subdomains();
    const Vec b = m.ext_out.head(n_own);
    row_stiffness_.assign(n_own, 1.0);
    has_row_stiffness_ = true;
    for (int k = 0; k < n_own; ++k)
      if (a[k] > 0 && b[k] > 0) row_stiffness_[k] = b[k] / a[k];
  }
  m.pairs = rs;
  m.combine_subdomains();
  m.gather(m.ext_out.head(n_own).eval());
  const Vec W = m.ext_in;
  m.pairs = rs.cwiseProduct(bpair);
  m.combine_subdomains();
  m.gather(m.ext_out.head(n_own).eval());
  const Vec V = m.ext_in;
  scaled_value_.resize(nsub);
  for (int s = 0; s < nsub; ++s) {
    scaled_value_[s].resize(m.rows[s].size());
    for (size_t e = 0; e < m.rows[s].size(); ++e) {
      const BRowEntry& r = m.rows[s][e];
      const double w = W[r.k];
      double v = r.value;
      if (w > 0 && r.cls == RowClass::node && !exact_node_scaling_) v = r.value - V[r.k] / w;
      if (w > 0 && r.cls == RowClass::object)
        v = 2.0 * r.value * (1.0 - rs[m.pair_first[s] + r.j] / w);
      scaled_value_[s][e] = v;
    }
  }
  if (!exact_node_scaling_) return;
  // Nodes with per-node gluing rows and no groups: the rows are an orthonormal basis of the
  // differences of the node's m copies, so B_g^T B_g = I - 11^T / m there and the sum over the
  // copies of a node is m (v_e - (B_g^T B_g v)_e), computable from any copy e. The weights are
  // delta_e = rho_e / sum_c rho_c, and B_D = B_g (I - delta 1^T) on the node: applied in
  // apply_preconditioner as u - 1 (delta^T u) after B_g^T and v - delta (1^T v) before B_g.
  node_row_positions_.resize(nsub), node_row_copies_.resize(nsub), node_row_delta_.resize(nsub);
  scaling_w_.resize(nsub), scaling_q_.resize(nsub), scaling_sums_.resize(nsub);
  std::vector<Vec> rv(nsub);
  for (int s = 0; s < nsub; ++s) {
    const int nb = local_[s]->size();
    scaling_w_[s] = Vec::Zero(nb), scaling_q_[s] = Vec::Zero(nb), scaling_sums_[s] = Vec::Zero(nb);
    rv[s] = Vec::Zero(nb);
    const int dpn = dofs_per_node[s];
    for (size_t e = 0; e < m.rows[s].size(); ++e) {
      const BRowEntry& r = m.rows[s][e];
      if (r.cls != RowClass::node) continue;
      node_row_positions_[s].push_back(interface_position_[s][e]);
      node_row_copies_[s].push_back(node_copies_[s][r.dof / dpn]);
      rv[s][interface_position_[s][e]] = rho[s][e];
    }
    // unique positions (a node dof carries several rows); copies follow their positions
    std::vector<size_t> idx(node_row_positions_[s].size());
    std::iota(idx.begin(), idx.end(), 0);
    std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) {
      return node_row_positions_[s][a] < node_row_positions_[s][b];
    });
    std::vector<int> pos, cop;
    for (size_t i : idx)
      if (pos.empty() || pos.back() != node_row_positions_[s][i])
        pos.push_back(node_row_positions_[s][i]), cop.push_back(node_row_copies_[s][i]);
    node_row_positions_[s] = pos;
    node_row_copies_[s].assign(cop.begin(), cop.end());
  }
  node_copies_ = {};
  std::vector<Vec> rsum(nsub);
  for (int s = 0; s < nsub; ++s) rsum[s] = Vec::Zero(local_[s]->size());
  copy_sums(m, rv, rsum);
  for (int s = 0; s < nsub; ++s) {
    node_row_delta_[s].resize(node_row_positions_[s].size());
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i) {
      const int p = node_row_positions_[s][i];
      node_row_delta_[s][i] = rsum[s][p] > 0 ? rv[s][p] / rsum[s][p] : 1.0 / node_row_copies_[s][i];
    }
  }
}

void DualPreconditioner::gluing_BtB(Multipliers& m, const std::vector<Vec>& w,
                                    std::vector<Vec>& q) {
  const int nsub = m.subdomains(), n_own = m.layout.n_owned();
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    for (int j = m.pair_first[s]; j < m.pair_first[s + 1]; ++j) m.pairs[j] = 0.0;
    double* f = m.pairs.data() + m.pair_first[s];
    const int* pos = interface_position_[s].data();
    const auto& rows = m.rows[s];
    for (size_t e = 0; e < rows.size(); ++e)
      if (rows[e].cls == RowClass::node) f[rows[e].j] += rows[e].value * w[s][pos[e]];
  }
  m.combine_subdomains();
  m.ext_in.head(n_own) = m.ext_out.head(n_own);
  m.layout.forward(m.ext_in.data());
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    q[s].setZero();
    const int* pos = interface_position_[s].data();
    const auto& rows = m.rows[s];
    for (size_t e = 0; e < rows.size(); ++e)
      if (rows[e].cls == RowClass::node) q[s][pos[e]] += rows[e].value * m.ext_in[rows[e].k];
  }
}

void DualPreconditioner::copy_sums(Multipliers& m, std::vector<Vec>& v, std::vector<Vec>& sums) {
  gluing_BtB(m, v, scaling_q_);
  const int nsub = m.subdomains();
  for (int s = 0; s < nsub; ++s)
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i) {
      const int p = node_row_positions_[s][i];
      sums[s][p] = node_row_copies_[s][i] * (v[s][p] - scaling_q_[s][p]);
    }
}

void DualPreconditioner::apply(Multipliers& m, const Vec& x, Vec& y) {
  if (!built()) throw std::logic_error("apply_preconditioner: no preconditioner was built");
  m.gather(x);
  const int nsub = m.subdomains();
  const bool scaled = !scaled_value_.empty(), nodes = exact_node_scaling_;
  auto value = [&](int s, size_t e) { return scaled ? scaled_value_[s][e] : m.rows[s][e].value; };
  if (!nodes) {  // one pass: B_D^T, the local operator, B_D
#pragma omp parallel for schedule(dynamic)
    for (int s = 0; s < nsub; ++s) {
      const auto& rows = m.rows[s];
      const int* pos = interface_position_[s].data();
      double* in = in_[s].data();
      double* out = out_[s].data();
      in_[s].setZero();
      for (size_t e = 0; e < rows.size(); ++e)  // B_D^T x on the interface
        in[pos[e]] += value(s, e) * m.ext_in[rows[e].k];
      local_[s]->apply(in, out);
      double* f = m.pairs.data() + m.pair_first[s];
      for (int j = m.pair_first[s]; j < m.pair_first[s + 1]; ++j) m.pairs[j] = 0.0;
      for (size_t e = 0; e < rows.size(); ++e)  // B_D (S B_D^T x)
        f[rows[e].j] += value(s, e) * out[pos[e]];
    }
    m.combine_subdomains();
    y = m.ext_out.head(m.layout.n_owned());
    return;
  }
  // Exact node scaling (build_scaling): the gluing part of B^T x on node dofs is corrected by
  // u - 1 (delta^T u), and before B the local result by v - delta (1^T v).
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    const auto& rows = m.rows[s];
    const int* pos = interface_position_[s].data();
    in_[s].setZero(), scaling_w_[s].setZero();
    for (size_t e = 0; e < rows.size(); ++e) {
      const double v = value(s, e) * m.ext_in[rows[e].k];
      if (rows[e].cls == RowClass::node)
        scaling_w_[s][pos[e]] += v;  // B_g^T x
      else
        in_[s][pos[e]] += v;
    }
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i) {  // u_g kept in out_, w = delta u_g
      const int p = node_row_positions_[s][i];
      out_[s][p] = scaling_w_[s][p];
      scaling_w_[s][p] *= node_row_delta_[s][i];
    }
  }
  copy_sums(m, scaling_w_, scaling_sums_);  // delta^T u over each node's copies
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i) {
      const int p = node_row_positions_[s][i];
      in_[s][p] += out_[s][p] - scaling_sums_[s][p];
    }
    local_[s]->apply(in_[s].data(), out_[s].data());
    scaling_w_[s].setZero();
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i)
      scaling_w_[s][node_row_positions_[s][i]] = out_[s][node_row_positions_[s][i]];
  }
  copy_sums(m, scaling_w_, scaling_sums_);  // 1^T v over each node's copies
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    const auto& rows = m.rows[s];
    const int* pos = interface_position_[s].data();
    scaling_w_[s] = out_[s];
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i)
      scaling_w_[s][node_row_positions_[s][i]] -=
          node_row_delta_[s][i] * scaling_sums_[s][node_row_positions_[s][i]];
    double* f = m.pairs.data() + m.pair_first[s];
    for (int j = m.pair_first[s]; j < m.pair_first[s + 1]; ++j) m.pairs[j] = 0.0;
    for (size_t e = 0; e < rows.size(); ++e)
      f[rows[e].j] +=
          value(s, e) * (rows[e].cls == RowClass::node ? scaling_w_[s][pos[e]] : out_[s][pos[e]]);
  }
  m.combine_subdomains();
  y = m.ext_out.head(m.layout.n_owned());
}

long DualPreconditioner::bytes() const {
  long b = 0;
  for (const auto& p : local_) b += p ? p->bytes() : 0;
  for (const auto& v : interface_position_) b += 4 * static_cast<long>(v.size());
  for (const auto& v : scaled_value_) b += 8 * static_cast<long>(v.size());
  return b;
}

}  // namespace htfeti
