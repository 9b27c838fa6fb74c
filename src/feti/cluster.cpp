#include "htfeti/feti/cluster.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "htfeti/clock.hpp"
#include "htfeti/errors.hpp"
#include "htfeti/parallel/blas_buffers.hpp"

// LAPACK (OpenBLAS)
extern "C" void dgetrf_(const int* m, const int* n, double* a, const int* lda, int* ipiv,
                        int* info);
extern "C" void dgecon_(const char* norm, const int* n, const double* a, const int* lda,
                        const double* anorm, double* rcond, double* work, int* iwork, int* info);

namespace htfeti {

DualOperator parse_dual_operator(const std::string& name) {
  return parse_name(kDualOperatorNames, name, "dual operator");
}

std::string to_string(DualOperator value) { return name_of(kDualOperatorNames, value); }

namespace {

// An orthonormal basis of Null(A) (A is O(1): orthonormal rows times orthonormal columns): the
// trailing columns of Q in the column-pivoted QR of A^T, whose leading columns span the row space
// of A. (A rank-revealing QR rather than an SVD: the caller makes the basis canonical, so only the
// subspace matters, and Eigen's SVDs cost a minute of compile time per build.)
Eigen::MatrixXd null_space(const Eigen::MatrixXd& A) {
  const int n = static_cast<int>(A.cols());
  if (A.rows() == 0) return Eigen::MatrixXd::Identity(n, n);
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A.transpose());
  const Eigen::VectorXd r = qr.matrixR().diagonal().cwiseAbs();  // non-increasing
  int rank = 0;
  while (rank < r.size() && r[rank] > 1e-9) ++rank;
  const Eigen::MatrixXd Q = qr.householderQ();
  return Q.rightCols(n - rank);
}

// The cluster kernel N = Null(CR) made canonical: the coefficients beta_J it fixes are chosen
// greedily in coefficient order (rows of N independent of those chosen before), N <- N N_J^{-1}
// (so N_J = I), then orthonormalized column by column. Returns J.
std::vector<int> canonical_kernel(const Eigen::MatrixXd& CR, int id, Eigen::MatrixXd& N_out) {
  const int nk = static_cast<int>(CR.cols());
  const Eigen::MatrixXd N0 = null_space(CR);
  const int dk = static_cast<int>(N0.cols());
  std::vector<int> J;
  {
    Eigen::MatrixXd basis(dk, dk);
    int r = 0;
    for (int g = 0; g < nk && r < dk; ++g) {
      Eigen::VectorXd v = N0.row(g).transpose();
      const double n0 = v.norm();
      if (n0 < 1e-8) continue;
      for (int pass = 0; pass < 2; ++pass)
        for (int q = 0; q < r; ++q) v -= basis.col(q).dot(v) * basis.col(q);
      if (v.norm() < 1e-6 * n0) continue;
      basis.col(r++) = v.normalized();
      J.push_back(g);
    }
    if (r < dk)
      throw std::runtime_error("cluster " + std::to_string(id) + ": kernel selection failed");
  }
  if (dk > 0) {
    Eigen::MatrixXd NJ(dk, dk);
    for (int j = 0; j < dk; ++j) NJ.row(j) = N0.row(J[j]);
    Eigen::MatrixXd N = N0 * NJ.inverse();
    for (int j = 0; j < dk; ++j) {
      for (int pass = 0; pass < 2; ++pass)
        for (int q = 0; q < j; ++q) N.col(j) -= N.col(q).dot(N.col(j)) * N.col(q);
      N.col(j).normalize();
    }
    N_out = N;
  } else {
    N_out = Eigen::MatrixXd(nk, 0);
  }
  return J;
}

// LAPACK's estimate (dgecon: Higham's estimator, O(n^2) flops) of the reciprocal condition
// number in the 1-norm, from dgetrf's factors of A and ||A||_1. (Eigen's PartialPivLU::rcond()
// computes the same estimate, in 0.04 s for n = 1,242.) -1 if LAPACK refuses the arguments.
double lu_rcond(const Eigen::MatrixXd& lu, double anorm) {
  const int n = static_cast<int>(lu.rows());
  if (n == 0) return 1;
  double rcond = 0;
  int info = 0;
  std::vector<double> work(4 * static_cast<size_t>(n));
  std::vector<int> iwork(n);
  const BlasOnOneThread one;  // the same estimate on any number of threads
  dgecon_("1", &n, lu.data(), &n, &anorm, &rcond, work.data(), iwork.data(), &info);
  return info == 0 ? rcond : -1;
}

// The columns of C_i^T by object: columns whose entries share a node (a face's or an edge's
// averages, the differences at a vertex) in one block, blocks in the order of their first
// column, columns ascending within each. Depends only on C_i^T, so equal subdomains get equal
// blocks, whichever rank holds them.
std::vector<std::vector<int>> object_blocks(const Eigen::MatrixXd& Ct, int dofs_per_node) {
  const int nc = static_cast<int>(Ct.cols());
  std::vector<int> parent(nc);
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  std::vector<int> column_at(Ct.rows() / dofs_per_node + 1, -1);  // a column touching the node
  for (int col = 0; col < nc; ++col)
    for (Eigen::Index r = 0; r < Ct.rows(); ++r) {
      if (Ct(r, col) == 0.0) continue;
      int& at = column_at[r / dofs_per_node];
      if (at < 0) {
        at = col;
      } else {
        const int a = root(at), b = root(col);
        if (a != b) parent[std::max(a, b)] = std::min(a, b);
      }
    }
  std::vector<std::vector<int>> blocks;
  std::vector<int> block_of(nc, -1);
  for (int col = 0; col < nc; ++col) {
    int& b = block_of[root(col)];
    if (b < 0) {
      b = static_cast<int>(blocks.size());
      blocks.emplace_back();
    }
    blocks[b].push_back(col);
  }
  return blocks;
}

}  // namespace

Cluster::Cluster(int id, std::vector<Subdomain*> subs, std::vector<std::vector<ConstraintEntry>> C,
                 Ordering ordering, std::vector<std::vector<Subdomain::BEntry>> b,
                 std::vector<int> nmult, DualOperator kind, SubdomainCache* cache,
                 Precision precision, bool by_object, bool single_sweeps)
    : id_(id), subs_(std::move(subs)), explicit_(kind != DualOperator::implicit) {
  if (kind == DualOperator::automatic)
    throw std::logic_error("cluster " + std::to_string(id) + ": the dual operator is not chosen");
  const int s = static_cast<int>(subs_.size());
  // The cluster's dual operator (ClusterDualOperator): the explicit one's blocks are formed
  // below, while the factors are at hand; the implicit one keeps the rows of B~; the checked one
  // holds both.
  ExplicitClusterOperator* ex = nullptr;
  if (explicit_) {
    auto op = std::make_unique<ExplicitClusterOperator>(*this, nmult, precision);
    ex = op.get();
    if (kind == DualOperator::checked)
      dual_ = std::make_unique<CheckedClusterOperator>(
          std::move(op), std::make_unique<ImplicitClusterOperator>(*this, b, nmult));
    else
      dual_ = std::move(op);
    ex->F_.resize(s), ex->V_.resize(s), interface_.resize(s);
  } else {
    // Without primal constraints K~^+ is block diagonal and the implicit operator's solves can
    // read the factors' single-precision copies (solve_interface).
    single_ = use_single_ = single_sweeps && C.empty();
    dual_ = std::make_unique<ImplicitClusterOperator>(*this, std::move(b), nmult);
  }
  RegionError failure;
  // Parallel over the cluster's subdomains when the caller is not already parallel (few large
  // clusters per rank); nested inside a parallel loop over clusters this runs serially.
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    try {
      if (explicit_) {
        std::vector<int>& dofs = interface_[i];
        for (const auto& e : b[i]) dofs.push_back(e.dof);
        std::sort(dofs.begin(), dofs.end());
        dofs.erase(std::unique(dofs.begin(), dofs.end()), dofs.end());
        subs_[i]->factorize_with_interface_last(dofs, cache, ordering);
        ex->F_[i] = subs_[i]->dual_block(b[i], nmult[i], precision);
        ex->V_[i] = Eigen::MatrixXd::Zero(nmult[i], subs_[i]->kernel_dimension());
        for (const auto& e : b[i]) ex->V_[i].row(e.mult) += e.value * subs_[i]->kernel().row(e.dof);
      } else {
        subs_[i]->factorize(ordering, cache, single_copy(*subs_[i]));
      }
    } catch (const std::exception& e) {
      failure.record(e, "subdomain " + std::to_string(subs_[i]->id()) + ": ");
    }
  }
  failure.rethrow();

  const double t0 = seconds_now();
  beta_offset_.assign(s + 1, 0);
  for (int i = 0; i < s; ++i) beta_offset_[i + 1] = beta_offset_[i] + subs_[i]->kernel_dimension();
  const int nk = beta_offset_[s];
  nc_ = static_cast<int>(C.size());
  c_of_sub_.assign(s, {});
  cols_of_sub_.assign(s, {});
  for (int j = 0; j < nc_; ++j)
    for (const auto& e : C[j]) {
      c_of_sub_[e.member].push_back({j, e.dof, e.value});
      auto& cols = cols_of_sub_[e.member];
      if (cols.empty() || cols.back() != j) cols.push_back(j);
    }
  // Cluster kernel N = Null(C R), made canonical (canonical_kernel).
  Eigen::MatrixXd CR = Eigen::MatrixXd::Zero(nc_, nk);
  for (int i = 0; i < s; ++i)
    for (const auto& e : c_of_sub_[i])
      CR.row(e.constraint).segment(beta_offset_[i], subs_[i]->kernel_dimension()) +=
          e.value * subs_[i]->kernel().row(e.dof);
  // The kernel (a serial dense QR) and W_i = K_i^+ C_i^T (solves, in parallel over the members)
  // at the same time: one thread takes the kernel, then joins the solves. Without constraints
  // (nc_ = 0) the kernel is every beta and there is nothing more to set up.
  std::vector<int> J;
  W_.resize(nc_ > 0 ? s : 0);
  RegionError werr;
#pragma omp parallel if (!omp_in_parallel() && s > 1 && nc_ > 0)
  {
#pragma omp single nowait
    {
      try {
        J = canonical_kernel(CR, id, N_);
      } catch (const std::exception& e) {
        werr.record(e);
      }
    }
#pragma omp for schedule(dynamic)
    for (int i = 0; i < static_cast<int>(W_.size()); ++i) {
      try {
        const auto& cols = cols_of_sub_[i];
        Eigen::MatrixXd Ct = Eigen::MatrixXd::Zero(subs_[i]->size(), static_cast<int>(cols.size()));
        for (const auto& e : c_of_sub_[i]) {
          const int col = static_cast<int>(
              std::lower_bound(cols.begin(), cols.end(), e.constraint) - cols.begin());
          Ct(e.dof, col) += e.value;
        }
        // One multi-column solve per object (by_object), or for all columns; equal subdomains
        // share an object's solve and, with equal C_i (a box), the whole of W_i.
        W_[i] = by_object
                    ? subs_[i]->pinv_many_shared(Ct, object_blocks(Ct, subs_[i]->dofs_per_node()))
                    : subs_[i]->pinv_many_shared(Ct);
      } catch (const std::exception& e) {
        werr.record(e, "subdomain " + std::to_string(subs_[i]->id()) + ": ");
      }
    }
  }
  werr.rethrow();
  beta_index_.assign(nk, -1);
  int dim = nc_;
  for (int g = 0; g < nk; ++g)
    if (std::find(J.begin(), J.end(), g) == J.end()) beta_index_[g] = dim++;
  if (dim == 0) {
    rhs_.resize(0);
    sol_.resize(0);
    return;
  }

  // The dense saddle-point matrix.
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(dim, dim);
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    // (C K^+ C^T)_{j, cols[col]} += C_i[j] . W_i[:, col]
    for (const auto& e : c_of_sub_[i])
      for (int col = 0; col < W_[i]->cols(); ++col)
        S(e.constraint, cols[col]) += e.value * (*W_[i])(e.dof, col);
  }
  for (int g = 0; g < nk; ++g) {
    if (beta_index_[g] < 0) continue;
    for (int j = 0; j < nc_; ++j) {
      S(j, beta_index_[g]) -= CR(j, g);
      S(beta_index_[g], j) -= CR(j, g);
    }
  }
  // Equilibration: S' = D S D with D = 1/sqrt(a) on mu and sqrt(a) on beta, a = max diagonal of
  // C K^+ C^T, so both blocks are O(1) whatever the stiffness scale.
  double a = 0;
  for (int j = 0; j < nc_; ++j) a = std::max(a, S(j, j));
  if (!(a > 0)) a = 1;
  dscale_.resize(dim);
  for (int j = 0; j < dim; ++j) dscale_[j] = j < nc_ ? 1.0 / std::sqrt(a) : std::sqrt(a);
  const Eigen::MatrixXd Ss = dscale_.asDiagonal() * S * dscale_.asDiagonal();
  if (explicit_) {  // U_i = B_i W_i
    for (int i = 0; i < s; ++i) {
      ex->U_.push_back(Eigen::MatrixXd::Zero(nmult[i], W_[i]->cols()));
      for (const auto& e : b[i]) ex->U_[i].row(e.mult) += e.value * W_[i]->row(e.dof);
    }
  }
  const double anorm = Ss.cwiseAbs().colwise().sum().maxCoeff();
  lu_ = Ss;
  pivots_.assign(dim, 0);
  int info = 0;
  {
    const BlasOnOneThread one;  // the same bits on any number of threads
    dgetrf_(&dim, &dim, lu_.data(), &dim, pivots_.data(), &info);
  }
  if (info < 0) throw std::logic_error("dgetrf: argument " + std::to_string(-info));
  for (int& p : pivots_) --p;
  setup_seconds_ = seconds_now() - t0;
  // info > 0: an exact zero pivot, rcond 0
  const double rcond = info > 0 ? 0.0 : lu_rcond(lu_, anorm);
  if (!(rcond > 1e-13))
    throw std::runtime_error("cluster " + std::to_string(id) +
                             ": singular cluster system (reciprocal condition number " +
                             std::to_string(rcond) + " after scaling)");
  rhs_.resize(dim);
  sol_.resize(dim);
}

void Cluster::solve_saddle() {
  rhs_.array() *= dscale_.array();
  sol_ = rhs_;  // P^T rhs, then L and U (as dgetrs)
  for (int i = 0; i < static_cast<int>(pivots_.size()); ++i)
    if (pivots_[i] != i) std::swap(sol_[i], sol_[pivots_[i]]);
  lu_.triangularView<Eigen::UnitLower>().solveInPlace(sol_);
  lu_.triangularView<Eigen::Upper>().solveInPlace(sol_);
  sol_.array() *= dscale_.array();
}

void Cluster::kernel_dot(int i, const Eigen::VectorXd& x, double* out) const {
  const int k = subs_[i]->kernel_dimension(), dk = kernel_dimension();
  const Eigen::VectorXd rx = subs_[i]->kernel().transpose() * x;  // small
  for (int j = 0; j < dk; ++j) out[j] += N_.col(j).segment(beta_offset_[i], k).dot(rx);
}

void Cluster::kernel_add(int i, const double* gamma, Eigen::VectorXd& u) const {
  const int k = subs_[i]->kernel_dimension(), dk = kernel_dimension();
  Eigen::VectorXd beta = Eigen::VectorXd::Zero(k);
  for (int j = 0; j < dk; ++j) beta += gamma[j] * N_.col(j).segment(beta_offset_[i], k);
  u.noalias() += subs_[i]->kernel() * beta;
}

double Cluster::kernel_entry(int i, int dof, int j) const {
  const int k = subs_[i]->kernel_dimension();
  return subs_[i]->kernel().row(dof).dot(N_.col(j).segment(beta_offset_[i], k));
}

void Cluster::release_factors() {
  for (auto* sd : subs_) {
    sd->release_factor();
    sd->release_matrix();
  }
}

void Cluster::refactor(Ordering ordering, SubdomainCache* cache, bool as_setup) {
  const int s = static_cast<int>(subs_.size());
  RegionError failure;
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    try {
      if (explicit_ && as_setup)
        subs_[i]->factorize_with_interface_last(interface_[i], cache, ordering);
      else
        subs_[i]->factorize(ordering, cache, single_copy(*subs_[i]));  // (single_: implicit only)
      subs_[i]->release_matrix();
    } catch (const std::exception& e) {
      failure.record(e);
    }
  }
  failure.rethrow();
}

long Cluster::explicit_bytes() const { return dual_->bytes(); }

long Cluster::single_bytes(std::unordered_set<const void*>* seen) const {
  long n = 0;
  for (const auto* sd : subs_)
    if (!seen || seen->insert(sd->single_data()).second) n += sd->single_bytes();
  return n;
}

void Cluster::apply_dual(const std::vector<Eigen::VectorXd>& lam,
                         std::vector<Eigen::VectorXd>& out) {
  dual_->apply(lam, out);
}

void ClusterDualOperator::apply(const std::vector<Eigen::VectorXd>& lam,
                                std::vector<Eigen::VectorXd>& out) {
  const size_t s = sizes_.size();
  if (lam.size() != s || out.size() != s)
    throw std::logic_error("cluster dual operator: " + std::to_string(lam.size()) + " and " +
                           std::to_string(out.size()) + " vectors for " + std::to_string(s) +
                           " subdomains");
  for (size_t i = 0; i < s; ++i)
    if (lam[i].size() != sizes_[i] || out[i].size() != sizes_[i])
      throw std::logic_error("cluster dual operator: subdomain " + std::to_string(i) + " has " +
                             std::to_string(sizes_[i]) + " multipliers, the vectors " +
                             std::to_string(lam[i].size()) + " and " +
                             std::to_string(out[i].size()));
  do_apply(lam, out);
}

ImplicitClusterOperator::ImplicitClusterOperator(Cluster& cluster,
                                                 std::vector<std::vector<Subdomain::BEntry>> b,
                                                 std::vector<int> nmult)
    : ClusterDualOperator(std::move(nmult)), cluster_(cluster), b_(std::move(b)) {
  for (const Subdomain* sd : cluster_.subdomains())
    xw_.push_back(Eigen::VectorXd::Zero(sd->size()));
}

void ImplicitClusterOperator::do_apply(const std::vector<Eigen::VectorXd>& lam,
                                       std::vector<Eigen::VectorXd>& out) {
  const int s = static_cast<int>(xw_.size());
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    xw_[i].setZero();
    for (const auto& e : b_[i]) xw_[i][e.dof] += e.value * lam[i][e.mult];  // B_i^T lam_i
  }
  cluster_.solve_interface(xw_);  // K~^+ B~^T lam
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    out[i].setZero();
    for (const auto& e : b_[i]) out[i][e.mult] += e.value * xw_[i][e.dof];  // B_i x_i
  }
}

CheckedClusterOperator::CheckedClusterOperator(std::unique_ptr<ClusterDualOperator> applied,
                                               std::unique_ptr<ClusterDualOperator> reference)
    : ClusterDualOperator(applied->sizes()),
      applied_(std::move(applied)),
      reference_(std::move(reference)) {
  if (reference_->sizes() != sizes())
    throw std::logic_error("checked dual operator: the two operators have different sizes");
  for (int n : sizes()) ref_.push_back(Eigen::VectorXd::Zero(n));
}

void CheckedClusterOperator::do_apply(const std::vector<Eigen::VectorXd>& lam,
                                      std::vector<Eigen::VectorXd>& out) {
  applied_->apply(lam, out);
  reference_->apply(lam, ref_);
  double diff = 0, norm = 0;  // over the cluster's subdomains, in a fixed order
  for (size_t i = 0; i < ref_.size(); ++i) {
    diff += (out[i] - ref_[i]).squaredNorm();
    norm += ref_[i].squaredNorm();
  }
  ++applications_;
  const double r = norm > 0   ? std::sqrt(diff / norm)
                   : diff > 0 ? std::numeric_limits<double>::infinity()
                              : 0.0;
  if (!(r <= max_relative_difference_)) max_relative_difference_ = r;  // NaN is kept
}

long ExplicitClusterOperator::bytes() const {
  long n = 0;
  for (const auto& f : F_) n += f.bytes();
  for (const auto& u : U_) n += 8 * u.size();
  for (const auto& v : V_) n += 8 * v.size();
  return n;
}

void ExplicitClusterOperator::do_apply(const std::vector<Eigen::VectorXd>& lam,
                                       std::vector<Eigen::VectorXd>& out) {
  Cluster& cl = cluster_;
  const int s = static_cast<int>(F_.size());
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) F_[i].multiply(lam[i].data(), out[i].data());  // the bottleneck
  if (cl.rhs_.size() == 0) return;
  cl.rhs_.setZero();
  for (int i = 0; i < s; ++i) {  // fixed order
    const auto& cols = cl.cols_of_sub_[i];
    for (int col = 0; col < static_cast<int>(cols.size()); ++col)
      cl.rhs_[cols[col]] += U_[i].col(col).dot(lam[i]);  // C K^+ B^T lam
    for (int q = 0; q < V_[i].cols(); ++q) {
      const int bi = cl.beta_index_[cl.beta_offset_[i] + q];
      if (bi >= 0) cl.rhs_[bi] = -V_[i].col(q).dot(lam[i]);  // -R_F^T B^T lam
    }
  }
  cl.solve_saddle();
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    const auto& cols = cl.cols_of_sub_[i];
    for (int col = 0; col < static_cast<int>(cols.size()); ++col)
      out[i].noalias() -= cl.sol_[cols[col]] * U_[i].col(col);
    for (int q = 0; q < V_[i].cols(); ++q) {
      const int bi = cl.beta_index_[cl.beta_offset_[i] + q];
      if (bi >= 0) out[i].noalias() += cl.sol_[bi] * V_[i].col(q);
    }
  }
}

long Cluster::dense_doubles(std::unordered_set<const void*>* seen) const {
  long n = 0;
  for (const auto& w : W_)
    if (w && (!seen || seen->insert(w.get()).second)) n += w->size();
  return rhs_.size() > 0 ? n + lu_.size() : n;
}

void Cluster::solve_interface(std::vector<Eigen::VectorXd>& x) {
  if (!use_single_) return solve(x);
  const int s = static_cast<int>(subs_.size());
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) subs_[i]->apply_pinv_single(x[i].data(), x[i].data());
}

// x_i <- K_i^+ x_i for every subdomain. A solve can throw (CHOLMOD's work arrays, made on the
// first solve, or a factor made again in double when a refinement fails): the exception is
// carried out of the parallel region, not left to end the process.
void Cluster::solve_each(std::vector<Eigen::VectorXd>& x) {
  const int s = static_cast<int>(subs_.size());
  RegionError failure;
#pragma omp parallel for schedule(dynamic) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    try {
      subs_[i]->apply_pinv(x[i].data(), x[i].data());
    } catch (const std::exception& e) {
      failure.record(e, "subdomain " + std::to_string(subs_[i]->id()) + ": ");
    }
  }
  failure.rethrow();
}

void Cluster::solve(std::vector<Eigen::VectorXd>& x) {
  const int s = static_cast<int>(subs_.size());
  if (rhs_.size() == 0) return solve_each(x);
  rhs_.setZero();
  for (int i = 0; i < s; ++i)
    for (int q = 0; q < subs_[i]->kernel_dimension(); ++q) {
      const int bi = beta_index_[beta_offset_[i] + q];
      if (bi >= 0) rhs_[bi] = -subs_[i]->kernel().col(q).dot(x[i]);
    }
  solve_each(x);               // x_i <- K_i^+ x_i
  for (int i = 0; i < s; ++i)  // C K^+ x, summed in a fixed order
    for (const auto& e : c_of_sub_[i]) rhs_[e.constraint] += e.value * x[i][e.dof];
  solve_saddle();
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && s > 1)
  for (int i = 0; i < s; ++i) {
    const auto& cols = cols_of_sub_[i];
    for (int col = 0; col < static_cast<int>(cols.size()); ++col)
      x[i].noalias() -= sol_[cols[col]] * W_[i]->col(col);
    for (int q = 0; q < subs_[i]->kernel_dimension(); ++q) {
      const int bi = beta_index_[beta_offset_[i] + q];
      if (bi >= 0) x[i].noalias() += sol_[bi] * subs_[i]->kernel().col(q);
    }
  }
}

}  // namespace htfeti
