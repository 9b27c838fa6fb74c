// The FETI preconditioner of the dual problem (preconditioner.hpp, docs/method.md
// "Preconditioners"): M^{-1} = B_D S B_D^T (Dirichlet) or B_D K B_D^T (lumped), with the scaled
// B_D of multiplicity or stiffness scaling; the local parts are LocalPreconditioner objects, set
// up with the clusters (dual_problem.cpp, stage 3). Cost of one application: one exchange each
// way and one local application per subdomain.
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "htfeti/feti/dual_problem.hpp"

namespace htfeti {

void DualProblem::build_scaling(const std::vector<std::vector<double>>& rho) {
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
  const int nsub = static_cast<int>(subs_.size()), n_own = layout_dual_.n_owned();
  const int npairs = static_cast<int>(flat_.size());
  Vec num = Vec::Zero(npairs), den = Vec::Zero(npairs), bpair = Vec::Zero(npairs);
  for (int s = 0; s < nsub; ++s)
    for (size_t e = 0; e < rows_[s].size(); ++e) {
      const Row& r = rows_[s][e];
      const int p = flat_off_[s] + r.j;
      num[p] += r.value * r.value * rho[s][e];
      den[p] += r.value * r.value;
      if (r.cls == RowClass::node) bpair[p] = r.value;
    }
  const Vec rs = (den.array() > 0).select(num.cwiseQuotient(den.cwiseMax(1e-300)), 0.0);
  flat_ = rs;
  combine_subdomains();
  gather_to_ext(ext_out_.head(n_own).eval());
  const Vec W = ext_in_;
  flat_ = rs.cwiseProduct(bpair);
  combine_subdomains();
  gather_to_ext(ext_out_.head(n_own).eval());
  const Vec V = ext_in_;
  bd_.resize(nsub);
  for (int s = 0; s < nsub; ++s) {
    bd_[s].resize(rows_[s].size());
    for (size_t e = 0; e < rows_[s].size(); ++e) {
      const Row& r = rows_[s][e];
      const double w = W[r.k];
      double v = r.value;
      if (w > 0 && r.cls == RowClass::node && !exact_node_scaling_) v = r.value - V[r.k] / w;
      if (w > 0 && r.cls == RowClass::object)
        v = 2.0 * r.value * (1.0 - rs[flat_off_[s] + r.j] / w);
      bd_[s][e] = v;
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
    const int nb = precond_[s]->size();
    scaling_w_[s] = Vec::Zero(nb), scaling_q_[s] = Vec::Zero(nb), scaling_sums_[s] = Vec::Zero(nb);
    rv[s] = Vec::Zero(nb);
    const int dpn = subs_[s]->dofs_per_node();
    for (size_t e = 0; e < rows_[s].size(); ++e) {
      const Row& r = rows_[s][e];
      if (r.cls != RowClass::node) continue;
      node_row_positions_[s].push_back(ipos_[s][e]);
      node_row_copies_[s].push_back(node_copies_[s][r.dof / dpn]);
      rv[s][ipos_[s][e]] = rho[s][e];
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
  for (int s = 0; s < nsub; ++s) rsum[s] = Vec::Zero(precond_[s]->size());
  copy_sums(rv, rsum);
  for (int s = 0; s < nsub; ++s) {
    node_row_delta_[s].resize(node_row_positions_[s].size());
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i) {
      const int p = node_row_positions_[s][i];
      node_row_delta_[s][i] = rsum[s][p] > 0 ? rv[s][p] / rsum[s][p] : 1.0 / node_row_copies_[s][i];
    }
  }
}

void DualProblem::gluing_BtB(const std::vector<Vec>& w, std::vector<Vec>& q) {
  const int nsub = static_cast<int>(subs_.size()), n_own = layout_dual_.n_owned();
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    for (int j = flat_off_[s]; j < flat_off_[s + 1]; ++j) flat_[j] = 0.0;
    double* f = flat_.data() + flat_off_[s];
    const int* pos = ipos_[s].data();
    const auto& rows = rows_[s];
    for (size_t e = 0; e < rows.size(); ++e)
      if (rows[e].cls == RowClass::node) f[rows[e].j] += rows[e].value * w[s][pos[e]];
  }
  combine_subdomains();
  ext_in_.head(n_own) = ext_out_.head(n_own);
  layout_dual_.forward(ext_in_.data());
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    q[s].setZero();
    const int* pos = ipos_[s].data();
    const auto& rows = rows_[s];
    for (size_t e = 0; e < rows.size(); ++e)
      if (rows[e].cls == RowClass::node) q[s][pos[e]] += rows[e].value * ext_in_[rows[e].k];
  }
}

void DualProblem::copy_sums(std::vector<Vec>& v, std::vector<Vec>& sums) {
  gluing_BtB(v, scaling_q_);
  const int nsub = static_cast<int>(subs_.size());
  for (int s = 0; s < nsub; ++s)
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i) {
      const int p = node_row_positions_[s][i];
      sums[s][p] = node_row_copies_[s][i] * (v[s][p] - scaling_q_[s][p]);
    }
}

void DualProblem::apply_preconditioner(const Vec& x, Vec& y) {
  if (precond_kind_ == PreconditionerKind::none)
    throw std::logic_error("apply_preconditioner: no preconditioner was built");
  gather_to_ext(x);
  const int nsub = static_cast<int>(subs_.size());
  const bool scaled = !bd_.empty(), nodes = exact_node_scaling_;
  auto value = [&](int s, size_t e) { return scaled ? bd_[s][e] : rows_[s][e].value; };
  if (!nodes) {  // one pass: B_D^T, the local operator, B_D
#pragma omp parallel for schedule(dynamic)
    for (int s = 0; s < nsub; ++s) {
      const auto& rows = rows_[s];
      const int* pos = ipos_[s].data();
      double* in = pin_[s].data();
      double* out = pout_[s].data();
      pin_[s].setZero();
      for (size_t e = 0; e < rows.size(); ++e)  // B_D^T x on the interface
        in[pos[e]] += value(s, e) * ext_in_[rows[e].k];
      precond_[s]->apply(in, out);
      double* f = flat_.data() + flat_off_[s];
      for (int j = flat_off_[s]; j < flat_off_[s + 1]; ++j) flat_[j] = 0.0;
      for (size_t e = 0; e < rows.size(); ++e)  // B_D (S B_D^T x)
        f[rows[e].j] += value(s, e) * out[pos[e]];
    }
    combine_subdomains();
    y = ext_out_.head(layout_dual_.n_owned());
    return;
  }
  // Exact node scaling (build_scaling): the gluing part of B^T x on node dofs is corrected by
  // u - 1 (delta^T u), and before B the local result by v - delta (1^T v).
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    const auto& rows = rows_[s];
    const int* pos = ipos_[s].data();
    pin_[s].setZero(), scaling_w_[s].setZero();
    for (size_t e = 0; e < rows.size(); ++e) {
      const double v = value(s, e) * ext_in_[rows[e].k];
      if (rows[e].cls == RowClass::node)
        scaling_w_[s][pos[e]] += v;  // B_g^T x
      else
        pin_[s][pos[e]] += v;
    }
    for (size_t i = 0; i < node_row_positions_[s].size();
         ++i) {  // u_g kept in pout_, w = delta u_g
      const int p = node_row_positions_[s][i];
      pout_[s][p] = scaling_w_[s][p];
      scaling_w_[s][p] *= node_row_delta_[s][i];
    }
  }
  copy_sums(scaling_w_, scaling_sums_);  // delta^T u over each node's copies
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i) {
      const int p = node_row_positions_[s][i];
      pin_[s][p] += pout_[s][p] - scaling_sums_[s][p];
    }
    precond_[s]->apply(pin_[s].data(), pout_[s].data());
    scaling_w_[s].setZero();
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i)
      scaling_w_[s][node_row_positions_[s][i]] = pout_[s][node_row_positions_[s][i]];
  }
  copy_sums(scaling_w_, scaling_sums_);  // 1^T v over each node's copies
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    const auto& rows = rows_[s];
    const int* pos = ipos_[s].data();
    scaling_w_[s] = pout_[s];
    for (size_t i = 0; i < node_row_positions_[s].size(); ++i)
      scaling_w_[s][node_row_positions_[s][i]] -=
          node_row_delta_[s][i] * scaling_sums_[s][node_row_positions_[s][i]];
    double* f = flat_.data() + flat_off_[s];
    for (int j = flat_off_[s]; j < flat_off_[s + 1]; ++j) flat_[j] = 0.0;
    for (size_t e = 0; e < rows.size(); ++e)
      f[rows[e].j] +=
          value(s, e) * (rows[e].cls == RowClass::node ? scaling_w_[s][pos[e]] : pout_[s][pos[e]]);
  }
  combine_subdomains();
  y = ext_out_.head(layout_dual_.n_owned());
}

long DualProblem::preconditioner_bytes() const {
  long b = 0;
  for (const auto& p : precond_) b += p ? p->bytes() : 0;
  for (const auto& v : ipos_) b += 4 * static_cast<long>(v.size());
  for (const auto& v : bd_) b += 8 * static_cast<long>(v.size());
  return b;
}

}  // namespace htfeti
