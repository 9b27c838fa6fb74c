// Shared helpers of the tests: the built-in models, global node numbering, dense constraint
// matrices and comparison with the undecomposed solution.
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseLU>
#include <cmath>
#include <map>
#include <memory>
#include <vector>

#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/model/model.hpp"
#include "reference.hpp"

namespace htfeti::test {

/// A DualProblem of a model; the model must outlive it.
inline std::unique_ptr<DualProblem> make_dual(const Model& model, const Comm& comm,
                                              const FetiOptions& options = {}) {
  return std::make_unique<DualProblem>(
      model.layout(), [&model](int s) { return model.input(s); }, comm, options);
}

/// The subdomain s of a model, assembled (not factored).
inline Subdomain make_subdomain(const Model& model, int s) {
  return Subdomain(model.input(s).system);
}

/// max |u - u_ref| over all copies of all nodes, relative to max |u_ref| (collective); u_ref is
/// indexed by global node (dofs_per_node entries per node).
inline double relative_error(const Model& model, const DualProblem& dual,
                             const std::vector<Eigen::VectorXd>& u, const Eigen::VectorXd& ref) {
  const int dpn = model.physics().dofs_per_node();
  double err = 0;
  for (size_t i = 0; i < u.size(); ++i) {
    const SubdomainMesh m = model.mesh(dual.subdomains()[i]->id());
    for (int k = 0; k < m.num_nodes(); ++k)
      for (int d = 0; d < dpn; ++d)
        err = std::max(err, std::abs(u[i][k * dpn + d] - ref[m.global_node[k] * dpn + d]));
  }
  return dual.comm().max(err) / ref.cwiseAbs().maxCoeff();
}

/// The undecomposed system of a one-subdomain input with its Dirichlet dofs eliminated:
/// A_ff u_f = b (b = f_f - K_fd u_d), as triplets of A_ff.
struct EliminatedSystem {
  std::vector<double> fixed;  ///< per dof: the Dirichlet value, NaN if free
  std::vector<int> free_of;   ///< per dof: index among the free dofs, -1 if fixed
  int nf = 0;
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd b;
  double kmax = 0;  ///< largest |K_ij| (a scale)

  /// The full vector from the free part.
  Eigen::VectorXd expand(const Eigen::VectorXd& x) const {
    Eigen::VectorXd u(static_cast<Eigen::Index>(fixed.size()));
    for (size_t i = 0; i < fixed.size(); ++i) u[i] = free_of[i] >= 0 ? x[free_of[i]] : fixed[i];
    return u;
  }
};

inline EliminatedSystem eliminate_dirichlet(const SubdomainInput& in, int dpn) {
  const int n = static_cast<int>(in.system.f.size());
  EliminatedSystem e;
  e.fixed.assign(n, std::nan(""));
  for (const auto& d : in.dirichlet) e.fixed[d.node * dpn + d.component] = d.value;
  e.free_of.assign(n, -1);
  for (int i = 0; i < n; ++i)
    if (std::isnan(e.fixed[i])) e.free_of[i] = e.nf++;
  e.b = Eigen::VectorXd::Zero(e.nf);
  for (int i = 0; i < n; ++i)
    if (e.free_of[i] >= 0) e.b[e.free_of[i]] = in.system.f[i];
  for (int col = 0; col < n; ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(in.system.K, col); it; ++it) {
      const int row = static_cast<int>(it.row());
      e.kmax = std::max(e.kmax, std::abs(it.value()));
      if (e.free_of[row] < 0) continue;
      if (e.free_of[col] >= 0)
        e.trip.emplace_back(e.free_of[row], e.free_of[col], it.value());
      else
        e.b[e.free_of[row]] -= it.value() * e.fixed[col];
    }
  return e;
}

/// The undecomposed problem of a one-subdomain model, Dirichlet dofs eliminated, solved by
/// Eigen's sparse LU (neither FETI nor CHOLMOD): u per global dof (node * dofs_per_node +
/// component), the energy 1/2 u'Ku - f'u, and whether the LU succeeded.
struct DirectSolution {
  Eigen::VectorXd u;
  double energy = 0;
  bool factored = false;
};
inline DirectSolution solve_one_subdomain(const Model& model) {
  const SubdomainInput in = model.input(0);
  const SubdomainMesh mesh = model.mesh(0);
  const int dpn = model.physics().dofs_per_node();
  const EliminatedSystem sys = eliminate_dirichlet(in, dpn);
  Eigen::SparseMatrix<double> A(sys.nf, sys.nf);
  A.setFromTriplets(sys.trip.begin(), sys.trip.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(A);
  DirectSolution out;
  out.factored = lu.info() == Eigen::Success;
  const Eigen::VectorXd u = sys.expand(lu.solve(sys.b));
  out.u.resize(static_cast<Eigen::Index>(model.num_nodes()) * dpn);
  for (int k = 0; k < mesh.num_nodes(); ++k)
    for (int d = 0; d < dpn; ++d) out.u[mesh.global_node[k] * dpn + d] = u[k * dpn + d];
  out.energy = 0.5 * u.dot(in.system.K * u) - in.system.f.dot(u);
  return out;
}

/// A vector of owned dual entries that depends only on global indices (rank-count independent).
inline Eigen::VectorXd pseudo_random(const DualProblem& dual, double seed) {
  Eigen::VectorXd v(dual.n_owned());
  for (int i = 0; i < v.size(); ++i) {
    const double g = static_cast<double>(dual.global_index(i));
    v[i] = std::sin(12.9898 * g + seed) * 43758.5453;
    v[i] -= std::floor(v[i]);
    v[i] -= 0.5;
  }
  return v;
}

/// Dense B~ (rows: multipliers in global order, columns: all subdomain dofs stacked) and C (all
/// clusters), built serially from every subdomain's rows.
struct DenseConstraints {
  Eigen::MatrixXd B, C;
  std::vector<MultiplierKind> kind;
  Eigen::VectorXd c;        ///< right-hand sides of the rows of B~
  std::vector<int> offset;  ///< first column of each subdomain
};

inline DenseConstraints dense_constraints(const Model& model, bool gluing_only = false) {
  const FetiLayout L = model.layout();
  std::vector<SubdomainInput> in;
  DenseConstraints d;
  d.offset.push_back(0);
  for (int s = 0; s < L.num_subdomains; ++s) {
    in.push_back(model.input(s));
    d.offset.push_back(d.offset.back() + static_cast<int>(in.back().system.f.size()));
  }
  std::map<RowKey, std::vector<std::pair<int, double>>> rows;
  std::map<RowKey, std::pair<MultiplierKind, double>> meta;
  for (int s = 0; s < L.num_subdomains; ++s) {
    std::vector<LocalRow> lr;
    subdomain_rows(L, in[s], lr);
    for (const auto& r : lr) {
      if (gluing_only && r.kind != MultiplierKind::gluing) continue;
      for (const auto& [dof, v] : r.entries) rows[r.key].push_back({d.offset[s] + dof, v});
      meta[r.key] = {r.kind, r.rhs};
    }
  }
  const int N = d.offset.back();
  d.B = Eigen::MatrixXd::Zero(static_cast<int>(rows.size()), N);
  d.c = Eigen::VectorXd::Zero(static_cast<int>(rows.size()));
  int r = 0;
  for (const auto& [key, entries] : rows) {
    for (const auto& [col, v] : entries) d.B(r, col) += v;
    d.kind.push_back(meta[key].first);
    d.c[r] = meta[key].second;
    ++r;
  }
  std::vector<std::vector<double>> crow;
  std::vector<Eigen::VectorXd> cr;
  for (int c = 0; c < L.num_clusters; ++c) {
    std::vector<const SubdomainInput*> members;
    for (int s = L.cluster_first[c]; s < L.cluster_first[c + 1]; ++s) members.push_back(&in[s]);
    for (const auto& row : cluster_primal_constraints(L, c, members)) {
      Eigen::VectorXd v = Eigen::VectorXd::Zero(N);
      for (const auto& e : row) v[d.offset[L.cluster_first[c] + e.member] + e.dof] += e.value;
      cr.push_back(v);
    }
  }
  d.C = Eigen::MatrixXd::Zero(static_cast<int>(cr.size()), N);
  for (size_t i = 0; i < cr.size(); ++i) d.C.row(static_cast<int>(i)) = cr[i].transpose();
  return d;
}

}  // namespace htfeti::test
