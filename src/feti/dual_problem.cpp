#include "htfeti/feti/dual_problem.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace htfeti {

namespace {
double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

DualProblem::DualProblem(const Decomposition& dec, const Comm& comm, const FetiOptions& options)
    : dec_(dec), comm_(comm) {
  const int P = comm.size(), me = comm.rank(), mm = dec.m() * dec.m();
  const auto [c0, c1] = dec.cluster_range(me, P);
  first_sub_ = c0 * mm;
  const int nsub = (c1 - c0) * mm;

  double t = now();
  subs_.resize(nsub);
#pragma omp parallel for schedule(dynamic) if (omp_get_max_threads() > 1)
  for (int s = 0; s < nsub; ++s) subs_[s] = std::make_unique<Subdomain>(dec, first_sub_ + s);
  setup_.assembly = now() - t;

  // Rows of B~ touching this rank's subdomains.
  t = now();
  std::vector<long long> touched;
  std::vector<int> touched_owner;
  std::vector<MultiplierKind> touched_kind;
  std::vector<double> touched_y, touched_scale;
  std::vector<std::vector<std::pair<long long, std::pair<int, double>>>> grows(nsub);
  n_dual_ = for_each_multiplier(dec, [&](const Multiplier& m) {
    if (m.kind == MultiplierKind::contact) ++n_inequalities_;
    bool mine = false;
    int lowest = std::numeric_limits<int>::max();
    for (const auto& e : m.entries) {
      lowest = std::min(lowest, e.subdomain);
      const int ls = e.subdomain - first_sub_;
      if (ls >= 0 && ls < nsub) {
        grows[ls].push_back({m.index, {e.dof, e.value}});
        mine = true;
      }
    }
    if (!mine) return;
    touched.push_back(m.index);
    touched_owner.push_back(dec.rank_of_subdomain(lowest, P));
    touched_kind.push_back(m.kind);
    touched_y.push_back(m.y);
    touched_scale.push_back(m.scale);
  });
  layout_ = DualLayout(comm, touched, touched_owner);
  const int n_ext = layout_.n_ext(), n_own = layout_.n_owned();
  owner_.assign(n_ext, me);
  kind_.assign(n_own, MultiplierKind::gluing);
  contact_y_.assign(n_own, 0.0);
  contact_scale_.assign(n_own, 1.0);
  for (size_t i = 0; i < touched.size(); ++i) {
    const int k = layout_.ext_index(touched[i]);
    owner_[k] = touched_owner[i];
    if (k < n_own) {
      kind_[k] = touched_kind[i];
      contact_y_[k] = touched_y[i];
      contact_scale_[k] = touched_scale[i];
    }
  }
  rows_.resize(nsub);
  for (int s = 0; s < nsub; ++s) {
    rows_[s].reserve(grows[s].size());
    for (const auto& [g, dv] : grows[s])
      rows_[s].push_back({layout_.ext_index(g), dv.first, dv.second});
  }
  setup_.constraints = now() - t;
  // Local numbering of the rows of B~ on each subdomain (distinct multipliers in extended order).
  mult_.resize(nsub);
  std::vector<std::vector<Subdomain::BEntry>> local_b(nsub);
  {
    std::vector<int> local_of(n_ext, -1);
    for (int s = 0; s < nsub; ++s) {
      for (const auto& r : rows_[s]) mult_[s].push_back(r.k);
      std::sort(mult_[s].begin(), mult_[s].end());
      mult_[s].erase(std::unique(mult_[s].begin(), mult_[s].end()), mult_[s].end());
      for (size_t j = 0; j < mult_[s].size(); ++j) local_of[mult_[s][j]] = static_cast<int>(j);
      for (const auto& r : rows_[s]) local_b[s].push_back({local_of[r.k], r.dof, r.value});
    }
  }
  explicit_ = options.dual_operator == DualOperator::explicit_ ||
              (options.dual_operator == DualOperator::automatic &&
               dec.nodes_per_subdomain() >= kExplicitMinNodes);

  ordering_ = options.ordering;
  const double factor_bytes_estimate = 8.0 * 100.0 * nsub * dec.nodes_per_subdomain();
  factors_released_ =
      explicit_ && !options.keep_factors && factor_bytes_estimate > options.factor_budget_bytes;
  contrib_.resize(nsub);
  for (int s = 0; s < nsub; ++s) contrib_[s].assign(rows_[s].size(), 0.0);
  x_.resize(c1 - c0);
  for (int c = 0; c < c1 - c0; ++c)
    for (int i = 0; i < mm; ++i) x_[c].push_back(Vec::Zero(subs_[c * mm + i]->size()));

  t = now();
  clusters_.resize(c1 - c0);
  // Threads run over clusters when there are enough of them, else inside each cluster.
  outer_parallel_ = omp_get_max_threads() > 1 && c1 - c0 >= omp_get_max_threads();
  std::string error;
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = c0; c < c1; ++c) {
    std::vector<Subdomain*> members;
    std::vector<std::vector<Subdomain::BEntry>> b;
    std::vector<int> nmult;
    for (int i = 0; i < mm; ++i) {
      const int s = (c - c0) * mm + i;
      members.push_back(subs_[s].get());
      b.push_back(std::move(local_b[s]));
      nmult.push_back(static_cast<int>(mult_[s].size()));
    }
    try {
      clusters_[c - c0] = std::make_unique<Cluster>(dec, c, std::move(members), options.ordering,
                                                    std::move(b), std::move(nmult), explicit_);
      // The cluster's part of d = B~ K~^+ f, while its factors are at hand.
      cluster_rhs_from_ext(c - c0, true, 0.0);
      clusters_[c - c0]->solve(x_[c - c0]);
      b_of_x(c - c0);
      if (factors_released_) clusters_[c - c0]->release_factors();
    } catch (const std::exception& e) {
#pragma omp critical
      error = e.what();
    }
  }
  if (!error.empty()) throw std::runtime_error(error);
  for (auto& sd : subs_) sd->release_matrix();  // factored: K_i is no longer needed
  setup_.factorization = now() - t;
  for (const auto& c : clusters_) setup_.cluster_setup += c->setup_seconds();
  lam_.resize(clusters_.size());
  out_.resize(clusters_.size());
  for (size_t c = 0; c < clusters_.size(); ++c)
    for (int i = 0; i < mm; ++i) {
      lam_[c].push_back(Vec::Zero(mult_[c * mm + i].size()));
      out_[c].push_back(Vec::Zero(mult_[c * mm + i].size()));
    }

  // G~ rows: (G~)_{c,k} = R~_c . b_k = kernel value * sum of row k's coefficients on cluster c.
  t = now();
  g_rows_.resize(clusters_.size());
  std::vector<double> acc(n_ext, 0.0);
  std::vector<int> hit;
  for (size_t c = 0; c < clusters_.size(); ++c) {
    hit.clear();
    for (int i = 0; i < mm; ++i)
      for (const auto& r : rows_[c * mm + i]) {
        if (acc[r.k] == 0.0) hit.push_back(r.k);
        acc[r.k] += r.value * clusters_[c]->kernel_value();
      }
    std::sort(hit.begin(), hit.end());
    hit.erase(std::unique(hit.begin(), hit.end()), hit.end());
    for (int k : hit) {
      if (acc[k] != 0.0) g_rows_[c].push_back({k, acc[k]});
      acc[k] = 0.0;
    }
  }
  ext_in_ = Vec::Zero(n_ext);
  ext_out_ = Vec::Zero(n_ext);
  coarse_work_ = Vec::Zero(coarse_dimension());

  assemble_coarse(std::vector<double>(n_own, 1.0), coarse_factor_);

  // d = B~ K~^+ f, e~ = R~^T f, lambda~ = G~^T (G~G~^T)^{-1} e~.
  scatter_contrib();  // d: the clusters' parts were computed with their setup
  contrib_ = {};      // needed for nothing else
  layout_.reverse_add(ext_out_.data());
  d_ = ext_out_.head(n_own);
  e_ = Vec::Zero(coarse_dimension());
  for (size_t c = 0; c < clusters_.size(); ++c) {
    double sum = 0;
    for (int i = 0; i < mm; ++i) sum += subs_[c * mm + i]->f().sum();
    e_[clusters_[c]->id()] = clusters_[c]->kernel_value() * sum;
  }
  comm_.sum_in_place(e_.data(), static_cast<int>(e_.size()));
  coarse_work_ = e_;
  coarse_solve(coarse_work_);
  lambda_tilde_.resize(n_own);
  apply_Gt(coarse_work_, lambda_tilde_);
  lower_.resize(n_own);
  for (int k = 0; k < n_own; ++k)
    lower_[k] =
        kind_[k] == MultiplierKind::contact ? 0.0 : -std::numeric_limits<double>::infinity();
  setup_.coarse = now() - t;
}

void DualProblem::gather_to_ext(const Vec& owned) {
  ext_in_.head(layout_.n_owned()) = owned;
  layout_.forward(ext_in_.data());
}

void DualProblem::cluster_rhs_from_ext(int c, bool add_f, double sign) {
  const int mm = dec_.m() * dec_.m();
  for (int i = 0; i < mm; ++i) {
    Vec& x = x_[c][i];
    if (add_f)
      x = subs_[c * mm + i]->f();
    else
      x.setZero();
    if (sign != 0.0)
      for (const auto& r : rows_[c * mm + i]) x[r.dof] += sign * r.value * ext_in_[r.k];
  }
}

void DualProblem::b_of_x(int c) {
  const int mm = dec_.m() * dec_.m();
  for (int i = 0; i < mm; ++i) {
    const Vec& x = x_[c][i];
    const auto& rows = rows_[c * mm + i];
    double* out = contrib_[c * mm + i].data();
    for (size_t j = 0; j < rows.size(); ++j) out[j] = rows[j].value * x[rows[j].dof];
  }
}

void DualProblem::scatter_contrib() {
  ext_out_.setZero();
  for (size_t s = 0; s < subs_.size(); ++s) {
    const auto& rows = rows_[s];
    const double* in = contrib_[s].data();
    for (size_t j = 0; j < rows.size(); ++j) ext_out_[rows[j].k] += in[j];
  }
}

template <class Body>
void DualProblem::for_each_cluster(Body body) {
  const int nc = static_cast<int>(clusters_.size());
#pragma omp parallel for schedule(dynamic) if (outer_parallel_)
  for (int c = 0; c < nc; ++c) body(c);
}

void DualProblem::apply_F(const Vec& lambda, Vec& y) {
  gather_to_ext(lambda);
  const int mm = dec_.m() * dec_.m();
  for_each_cluster([&](int c) {
    for (int i = 0; i < mm; ++i) {  // the cluster's part of lambda
      const auto& mult = mult_[c * mm + i];
      Vec& l = lam_[c][i];
      for (size_t j = 0; j < mult.size(); ++j) l[j] = ext_in_[mult[j]];
    }
    clusters_[c]->apply_dual(lam_[c], out_[c]);  // the bottleneck
  });
  ext_out_.setZero();  // F lambda, summed in a fixed order
  for (size_t c = 0; c < clusters_.size(); ++c)
    for (int i = 0; i < mm; ++i) {
      const auto& mult = mult_[c * mm + i];
      const Vec& o = out_[c][i];
      for (size_t j = 0; j < mult.size(); ++j) ext_out_[mult[j]] += o[j];
    }
  layout_.reverse_add(ext_out_.data());
  y = ext_out_.head(layout_.n_owned());
}

void DualProblem::apply_G(const Vec& lambda, Vec& coarse) {
  gather_to_ext(lambda);
  coarse.setZero(coarse_dimension());
  for (size_t c = 0; c < clusters_.size(); ++c) {
    double s = 0;
    for (const auto& [k, g] : g_rows_[c]) s += g * ext_in_[k];
    coarse[clusters_[c]->id()] = s;
  }
  comm_.sum_in_place(coarse.data(), static_cast<int>(coarse.size()));
}

void DualProblem::gt_into_ext(const Vec& coarse) {
  ext_out_.setZero();
  for (size_t c = 0; c < clusters_.size(); ++c) {
    const double z = coarse[clusters_[c]->id()];
    for (const auto& [k, g] : g_rows_[c]) ext_out_[k] += g * z;
  }
  layout_.reverse_add(ext_out_.data());
}

void DualProblem::apply_Gt(const Vec& coarse, Vec& lambda) {
  gt_into_ext(coarse);
  lambda = ext_out_.head(layout_.n_owned());
}

void DualProblem::project(const Vec& x, Vec& y) {
  apply_G(x, coarse_work_);    // G~ x
  coarse_solve(coarse_work_);  // (G~ G~^T)^{-1} G~ x
  gt_into_ext(coarse_work_);   // G~^T (G~ G~^T)^{-1} G~ x, owned part in ext_out_
  y = x - ext_out_.head(layout_.n_owned());
}

void DualProblem::assemble_coarse(const std::vector<double>& weight, SparseCholesky& factor) {
  // (G~ W G~^T)_{ab} = sum_k w_k g_ak g_bk. Every cluster sends (k, cluster, g_ak) to the owner of
  // k; owners form the products; all triplets are shared, and every rank factors the matrix.
  struct Item {
    long long k;
    int cluster;
    double g;
  };
  struct Triplet {
    int a, b;
    double v;
  };
  const int P = comm_.size();
  std::vector<std::vector<Item>> out(P);
  for (size_t c = 0; c < clusters_.size(); ++c)
    for (const auto& [k, g] : g_rows_[c])
      out[owner_[k]].push_back({layout_.global(k), clusters_[c]->id(), g});
  std::vector<int> scount(P), rcount(P), sdisp(P + 1, 0), rdisp(P + 1, 0);
  for (int r = 0; r < P; ++r) scount[r] = static_cast<int>(out[r].size() * sizeof(Item));
  MPI_Alltoall(scount.data(), 1, MPI_INT, rcount.data(), 1, MPI_INT, comm_.raw());
  for (int r = 0; r < P; ++r)
    sdisp[r + 1] = sdisp[r] + scount[r], rdisp[r + 1] = rdisp[r] + rcount[r];
  std::vector<Item> sbuf(sdisp[P] / sizeof(Item)), rbuf(rdisp[P] / sizeof(Item));
  for (int r = 0, pos = 0; r < P; ++r)
    for (const auto& it : out[r]) sbuf[pos++] = it;
  MPI_Alltoallv(sbuf.data(), scount.data(), sdisp.data(), MPI_BYTE, rbuf.data(), rcount.data(),
                rdisp.data(), MPI_BYTE, comm_.raw());
  std::stable_sort(rbuf.begin(), rbuf.end(), [](const Item& x, const Item& y) {
    return x.k != y.k ? x.k < y.k : x.cluster < y.cluster;
  });
  std::vector<Triplet> mine;
  for (size_t i = 0; i < rbuf.size();) {
    size_t j = i;
    while (j < rbuf.size() && rbuf[j].k == rbuf[i].k) ++j;
    const double w = weight[layout_.ext_index(rbuf[i].k)];
    if (w != 0.0)
      for (size_t a = i; a < j; ++a)
        for (size_t b = a; b < j; ++b) {
          int ca = rbuf[a].cluster, cb = rbuf[b].cluster;
          if (ca > cb) std::swap(ca, cb);
          mine.push_back({ca, cb, w * rbuf[a].g * rbuf[b].g});
        }
    i = j;
  }
  int nbytes = static_cast<int>(mine.size() * sizeof(Triplet));
  std::vector<int> counts(P), disp(P + 1, 0);
  MPI_Allgather(&nbytes, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_.raw());
  for (int r = 0; r < P; ++r) disp[r + 1] = disp[r] + counts[r];
  std::vector<Triplet> all(disp[P] / sizeof(Triplet));
  MPI_Allgatherv(mine.data(), nbytes, MPI_BYTE, all.data(), counts.data(), disp.data(), MPI_BYTE,
                 comm_.raw());
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(all.size());
  for (const auto& t : all) trip.emplace_back(t.a, t.b, t.v);
  Eigen::SparseMatrix<double> GGt(coarse_dimension(), coarse_dimension());
  GGt.setFromTriplets(trip.begin(), trip.end());
  factor = SparseCholesky(Ordering::amd);
  factor.factorize(GGt);
}

void DualProblem::apply_B(const std::vector<Vec>& u, Vec& out) {
  ext_out_.setZero();
  for (size_t s = 0; s < subs_.size(); ++s)
    for (const auto& r : rows_[s]) ext_out_[r.k] += r.value * u[s][r.dof];
  layout_.reverse_add(ext_out_.data());
  out = ext_out_.head(layout_.n_owned());
}

std::vector<DualProblem::Vec> DualProblem::reconstruct(const Vec& lambda) {
  const int mm = dec_.m() * dec_.m(), n_own = layout_.n_owned();
  gather_to_ext(lambda);
  std::vector<Vec> u(subs_.size());
  for_each_cluster([&](int c) {
    if (factors_released_) clusters_[c]->refactor(ordering_);
    cluster_rhs_from_ext(c, true, -1.0);  // f - B~^T lambda
    clusters_[c]->solve(x_[c]);
    for (int i = 0; i < mm; ++i) u[c * mm + i] = x_[c][i];
    if (factors_released_) clusters_[c]->release_factors();
  });
  // B u0 = d - F lambda; alpha solves G~ D G~^T alpha = G~ D (F lambda - d), D masking the
  // contact rows with lambda_i = 0 (paper, (10)).
  Vec r;
  apply_B(u, r);
  r = -r;
  std::vector<double> weight(n_own, 1.0);
  bool masked = false;
  for (int k = 0; k < n_own; ++k)
    if (kind_[k] == MultiplierKind::contact && !(lambda[k] > 0.0)) {
      weight[k] = 0.0;
      r[k] = 0.0;
      masked = true;
    }
  Vec alpha;
  apply_G(r, alpha);
  if (comm_.max(masked ? 1.0 : 0.0) > 0.0) {
    SparseCholesky masked_factor;
    assemble_coarse(weight, masked_factor);
    masked_factor.solve(alpha.data(), alpha.data());
  } else {
    coarse_solve(alpha);
  }
  for (size_t c = 0; c < clusters_.size(); ++c) {
    const double shift = alpha[clusters_[c]->id()] * clusters_[c]->kernel_value();
    for (int i = 0; i < mm; ++i) u[c * mm + i].array() += shift;
  }
  return u;
}

double DualProblem::energy(const std::vector<Vec>& u) const {
  double q = 0;
  for (size_t s = 0; s < subs_.size(); ++s) q += subs_[s]->energy(u[s]);
  return comm_.sum(q);
}

DualProblem::Kkt DualProblem::kkt(const std::vector<Vec>& u, const Vec& lambda) {
  Vec bu;
  apply_B(u, bu);
  double eq = 0, viol = 0, minmult = std::numeric_limits<double>::infinity(), compl_ = 0;
  bool any_contact = false;
  for (int k = 0; k < layout_.n_owned(); ++k) {
    if (kind_[k] != MultiplierKind::contact) {
      eq += bu[k] * bu[k];
      continue;
    }
    any_contact = true;
    const double c = contact_scale_[k];
    const double gap = -bu[k] / c;  // u_right - u_left
    const double force = c * lambda[k];
    viol = std::max(viol, -gap);
    minmult = std::min(minmult, force);
    compl_ = std::max(compl_, std::abs(force * gap));
  }
  Kkt r;
  r.equality_residual = std::sqrt(comm_.sum(eq));
  r.max_violation = comm_.max(viol);
  r.min_multiplier = comm_.sum(any_contact ? 1.0 : 0.0) > 0 ? comm_.min(minmult) : 0.0;
  r.complementarity = comm_.max(compl_);
  return r;
}

DualProblem::ContactData DualProblem::contact_data(const std::vector<Vec>& u, const Vec& lambda) {
  // Averages of the left copies (positive coefficients c/k_L) and right copies (-c/k_R).
  const int n_own = layout_.n_owned();
  Vec left = Vec::Zero(layout_.n_ext()), right = Vec::Zero(layout_.n_ext());
  // The kind of a multiplier is known on its owner: send a contact mark to the ghosts.
  std::vector<double> is_contact(layout_.n_ext(), 0.0);
  for (int k = 0; k < n_own; ++k) is_contact[k] = kind_[k] == MultiplierKind::contact ? 1.0 : 0.0;
  layout_.forward(is_contact.data());
  for (size_t s = 0; s < subs_.size(); ++s)
    for (const auto& r : rows_[s]) {
      if (is_contact[r.k] == 0.0) continue;
      if (r.value > 0)
        left[r.k] += r.value * u[s][r.dof];
      else
        right[r.k] -= r.value * u[s][r.dof];
    }
  layout_.reverse_add(left.data());
  layout_.reverse_add(right.data());
  std::vector<double> mine;
  for (int k = 0; k < n_own; ++k)
    if (kind_[k] == MultiplierKind::contact) {
      const double c = contact_scale_[k];
      mine.insert(mine.end(), {contact_y_[k], left[k] / c, right[k] / c, c * lambda[k]});
    }
  const int P = comm_.size();
  int count = static_cast<int>(mine.size());
  std::vector<int> counts(P), disp(P + 1, 0);
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, comm_.raw());
  for (int r = 0; r < P; ++r) disp[r + 1] = disp[r] + counts[r];
  std::vector<double> all(comm_.rank() == 0 ? disp[P] : 0);
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), disp.data(), MPI_DOUBLE, 0,
              comm_.raw());
  ContactData data;
  if (comm_.rank() != 0) return data;
  std::vector<std::array<double, 4>> rows(all.size() / 4);
  for (size_t i = 0; i < rows.size(); ++i)
    rows[i] = {all[4 * i], all[4 * i + 1], all[4 * i + 2], all[4 * i + 3]};
  std::sort(rows.begin(), rows.end());
  for (const auto& r : rows) {
    data.y.push_back(r[0]);
    data.u_left.push_back(r[1]);
    data.u_right.push_back(r[2]);
    data.multiplier.push_back(r[3]);
  }
  return data;
}

long DualProblem::factor_nonzeros() const {
  long n = 0;
  for (const auto& s : subs_) n += s->factor_nonzeros();
  return n;
}

}  // namespace htfeti

namespace htfeti {

long DualProblem::explicit_doubles() const {
  long n = 0;
  for (const auto& c : clusters_) n += c->explicit_doubles();
  return n;
}

long DualProblem::cluster_dense_doubles() const {
  long n = 0;
  for (const auto& c : clusters_) n += c->dense_doubles();
  return n;
}

}  // namespace htfeti
