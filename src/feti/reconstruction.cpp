// After the solve (paper, (10)): the primal solution u = K~^+ (f - B~^T lambda) + R~ alpha, its
// energy, the KKT checks of the report and the contact output (per-row data, nodal contact
// forces and the remaining gap for the VTU). Each is one pass over the subdomains and a few
// reductions; reconstruct() adds one K~^+ per cluster and one coarse solve.
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "htfeti/clock.hpp"
#include "htfeti/errors.hpp"
#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/parallel/memory.hpp"

namespace htfeti {

void DualProblem::apply_B(const std::vector<Vec>& u, Vec& out) {
  multipliers_.pairs.setZero();
  for (size_t s = 0; s < subs_.size(); ++s)
    for (const auto& r : multipliers_.rows[s])
      multipliers_.pairs[multipliers_.pair_first[s] + r.j] += r.value * u[s][r.dof];
  multipliers_.combine_subdomains();
  out = multipliers_.ext_out.head(multipliers_.layout.n_owned());
}

std::vector<DualProblem::Vec> DualProblem::reconstruct(const Vec& lambda) {
  const int n_own = multipliers_.layout.n_owned();
  multipliers_.gather(lambda);
  std::vector<Vec> u(subs_.size());
  std::string error;
  bool input_error = false;
  try {
    for_each_cluster([&](int c) {
      if (c == 0) inject_failure("reconstruction", comm_.rank());
      // Freed factors are rebuilt plain (ordering_, no interface last): solve() is all the
      // reconstruction needs, and that factor is cheaper (docs/method.md); u then
      // agrees with the kept factors' u to round-off.
      if (released_[c]) clusters_[c]->refactor(ordering_, factor_cache(), false);
      cluster_rhs_from_ext(c, true, -1.0);  // f - B~^T lambda
      clusters_[c]->solve(x_[c]);
      for (int i = 0; i < members(c); ++i) u[sub_of(c, i)] = x_[c][i];
      if (released_[c]) clusters_[c]->release_factors();
    });
  } catch (const std::bad_alloc&) {
    error = "out of memory in the reconstruction", input_error = true;
  } catch (const std::exception& e) {
    error = e.what();
  }
  comm_.agree(error, input_error);
  // B u0 = d + c - F lambda; alpha solves G~ D G~^T alpha = G~ D (c - B u0), D masking the
  // contact rows with lambda_i = 0 (paper, (10)) and the friction rows in slip.
  Vec r;
  apply_B(u, r);
  r = multipliers_.rhs - r;
  std::vector<double> weight(n_own, 1.0);
  bool masked = false;
  for (int k = 0; k < n_own; ++k) {
    const bool open = multipliers_.kind[k] == MultiplierKind::contact && !(lambda[k] > 0.0);
    // A friction row holds (t.u = 0) only in stick, below its bound.
    const bool slip =
        multipliers_.kind[k] == MultiplierKind::friction && friction_slips(k, lambda, 1e-10);
    if (open || slip) {
      weight[k] = 0.0;
      r[k] = 0.0;
      masked = true;
    }
  }
  Vec alpha;
  apply_G(r, alpha);
  if (comm_.max(masked ? 1.0 : 0.0) > 0.0) {
    reconstruction_null_ = coarse_.solve_weighted(weight, alpha);
  } else {
    coarse_solve(alpha);
  }
  for (size_t c = 0; c < clusters_.size(); ++c) {
    const double* a = &alpha[coarse_.first(clusters_[c]->id())];
    for (int i = 0; i < members(static_cast<int>(c)); ++i)
      clusters_[c]->kernel_add(i, a, u[sub_of(static_cast<int>(c), i)]);
  }
  return u;
}

double DualProblem::energy(const std::vector<Vec>& u) const {
  // Per-subdomain energies summed in subdomain order (rank-count independent).
  // Threads take subdomains (each rebuilds its K_i if it was freed: the cost of this function);
  // the sum below is in subdomain order, so the result does not depend on the thread count.
  std::vector<double> e(layout_.num_subdomains, 0.0);
  const int n = static_cast<int>(subs_.size());
  RegionError failure;  // (rebuilding K_i allocates: carried out of the region)
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < n; ++s) {
    try {
      e[subs_[s]->id()] = subs_[s]->energy(u[s]);
    } catch (const std::exception& ex) {
      failure.record(ex);
    }
  }
  failure.rethrow();
  if (comm_.size() > 1)
    MPI_Allreduce(MPI_IN_PLACE, e.data(), static_cast<int>(e.size()), MPI_DOUBLE, MPI_SUM,
                  comm_.raw());
  double q = 0;
  for (double v : e) q += v;
  return q;
}

DualProblem::Kkt DualProblem::kkt(const std::vector<Vec>& u, const Vec& lambda) {
  Vec bu;
  apply_B(u, bu);
  double viol = 0, minmult = std::numeric_limits<double>::infinity(), compl_ = 0;
  bool any_contact = false;
  Vec sq = Vec::Zero(multipliers_.layout.n_owned()), csq = sq;
  for (int k = 0; k < multipliers_.layout.n_owned(); ++k) {
    if (multipliers_.kind[k] == MultiplierKind::friction) continue;  // not an equality
    if (multipliers_.kind[k] != MultiplierKind::contact) {
      sq[k] = (bu[k] - multipliers_.rhs[k]) * (bu[k] - multipliers_.rhs[k]);
      csq[k] = multipliers_.rhs[k] * multipliers_.rhs[k];
      continue;
    }
    any_contact = true;
    // The row's force and its remaining gap in length units (W = 1 for node-to-node rows).
    const double s = multipliers_.contact_scale[k] * multipliers_.contact_weight[k];
    const double gap =
        (multipliers_.rhs[k] - bu[k]) / s;  // gap - n.(u_a - u_b), >= 0 when feasible
    const double force = s * lambda[k];
    viol = std::max(viol, -gap);
    minmult = std::min(minmult, force);
    compl_ = std::max(compl_, std::abs(force * gap));
  }
  Kkt r;
  r.equality_residual = std::sqrt(sum(sq));
  // ||u|| over all copies, per subdomain in subdomain order (rank-count independent).
  std::vector<double> usq(layout_.num_subdomains, 0.0);
  for (size_t s = 0; s < subs_.size(); ++s) usq[subs_[s]->id()] = u[s].squaredNorm();
  if (comm_.size() > 1)
    MPI_Allreduce(MPI_IN_PLACE, usq.data(), static_cast<int>(usq.size()), MPI_DOUBLE, MPI_SUM,
                  comm_.raw());
  double u2 = 0;
  for (double v : usq) u2 += v;
  r.equality_scale = std::sqrt(u2) + std::sqrt(sum(csq));
  r.max_violation = comm_.max(viol);
  r.min_multiplier = comm_.sum(any_contact ? 1.0 : 0.0) > 0 ? comm_.min(minmult) : 0.0;
  r.complementarity = comm_.max(compl_);
  return r;
}

DualProblem::ContactRowValues DualProblem::contact_row_values(const std::vector<Vec>& u,
                                                              const Vec& lambda) {
  // n.(avg u_a) from the entries on node a (coefficients scale n_i / k_a), n.(avg u_b) likewise.
  const int n_own = multipliers_.layout.n_owned();
  Vec a = Vec::Zero(multipliers_.layout.n_ext()), b = Vec::Zero(multipliers_.layout.n_ext());
  for (int side : {1, -1}) {
    multipliers_.pairs.setZero();
    for (size_t s = 0; s < subs_.size(); ++s)
      for (const auto& r : multipliers_.rows[s])
        if (r.side == side)
          multipliers_.pairs[multipliers_.pair_first[s] + r.j] += side * r.value * u[s][r.dof];
    multipliers_.combine_subdomains();
    (side > 0 ? a : b).head(n_own) = multipliers_.ext_out.head(n_own);
  }
  // Friction: the first tangential row of each contact row.
  std::vector<int> tangential_of(n_own, -1);
  for (int k = 0; k < n_own; ++k)
    if (multipliers_.kind[k] == MultiplierKind::friction) {
      const int other = multipliers_.friction_partner[k];
      if (other < 0 || k < other) tangential_of[multipliers_.friction_normal[k]] = k;
    }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ContactRowValues v;
  v.u_a = a.head(n_own), v.u_b = b.head(n_own);
  v.pressure = v.tangential = v.slip = v.state = Vec::Constant(n_own, nan);
  for (int k = 0; k < n_own; ++k) {
    if (multipliers_.kind[k] != MultiplierKind::contact) continue;
    const double s = multipliers_.contact_scale[k] * multipliers_.contact_weight[k];
    const double area = multipliers_.contact_area[k];
    if (area > 0) v.pressure[k] = s * lambda[k] / area;
    // The tangential traction on the body (2D: along t, signed; 3D: its length), the slip (the
    // tangential relative displacement: 2D along t, 3D its length) and the state.
    if (const int f = tangential_of[k]; f >= 0) {
      const int g = multipliers_.friction_partner[f];
      const double sf = multipliers_.contact_scale[f] * multipliers_.contact_weight[f];
      const double t1 = -sf * lambda[f], d1 = (a[f] - b[f]) / sf;
      const double t2 = g >= 0 ? -sf * lambda[g] : 0.0, d2 = g >= 0 ? (a[g] - b[g]) / sf : 0.0;
      const bool signed_1d = layout_.dim == 2;  // 3D: lengths, also for a single row
      if (area > 0) v.tangential[k] = (signed_1d ? t1 : std::hypot(t1, t2)) / area;
      v.slip[k] = signed_1d ? d1 : std::hypot(d1, d2);
      v.state[k] = !(lambda[k] > 0) ? 0.0 : friction_slips(f, lambda, 1e-6) ? 2.0 : 1.0;
    }
  }
  return v;
}

DualProblem::ContactData DualProblem::contact_data(const std::vector<Vec>& u, const Vec& lambda) {
  const int n_own = multipliers_.layout.n_owned();
  const ContactRowValues v = contact_row_values(u, lambda);
  std::vector<double> mine;
  for (int k = 0; k < n_own; ++k)
    if (multipliers_.kind[k] == MultiplierKind::contact) {
      const double s = multipliers_.contact_scale[k] * multipliers_.contact_weight[k];
      const auto& p = multipliers_.contact_point[k];
      mine.insert(mine.end(),
                  {p[0], p[1], p[2], v.u_a[k] / s, v.u_b[k] / s, multipliers_.contact_gap[k],
                   s * lambda[k], v.pressure[k], v.tangential[k], v.slip[k], v.state[k]});
    }
  constexpr int W = 11;
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
  std::vector<std::array<double, W>> rows(all.size() / W);
  for (size_t i = 0; i < rows.size(); ++i)
    for (int j = 0; j < W; ++j) rows[i][j] = all[W * i + j];
  std::sort(rows.begin(), rows.end());
  for (const auto& r : rows) {
    data.x.push_back(r[0]);
    data.y.push_back(r[1]);
    data.z.push_back(r[2]);
    data.u_a.push_back(r[3]);
    data.u_b.push_back(r[4]);
    data.gap.push_back(r[5]);
    data.force.push_back(r[6]);
    data.pressure.push_back(r[7]);
    data.tangential.push_back(r[8]);
    data.slip.push_back(r[9]);
    data.state.push_back(r[10]);
  }
  return data;
}

std::vector<DualProblem::ContactSummary> DualProblem::contact_summary(const std::vector<Vec>& u,
                                                                      const Vec& lambda,
                                                                      int conditions) {
  Vec bu;
  apply_B(u, bu);
  const int n_own = multipliers_.layout.n_owned();
  std::vector<ContactSummary> out(conditions);
  Vec force(n_own), area(n_own), tangential(n_own);
  for (int c = 0; c < conditions; ++c) {
    long long rows = 0, active = 0, friction_rows = 0, open = 0, stick = 0, slip = 0;
    double penetration = 0;
    force.setZero(), area.setZero(), tangential.setZero();
    for (int k = 0; k < n_own; ++k) {
      if (multipliers_.contact_condition[k] != c) continue;
      const double s = multipliers_.contact_scale[k] * multipliers_.contact_weight[k];
      if (multipliers_.kind[k] == MultiplierKind::contact) {
        ++rows;
        penetration = std::max(penetration, -(multipliers_.rhs[k] - bu[k]) / s);
        if (lambda[k] > 0) {
          ++active;
          force[k] = s * lambda[k];
          area[k] = multipliers_.contact_area[k];
        }
      } else if (multipliers_.kind[k] == MultiplierKind::friction) {
        // The force along the row's tangent; the state of its node (a 3D pair once).
        ++friction_rows;
        tangential[k] = -s * lambda[k];
        const int other = multipliers_.friction_partner[k];
        if (other >= 0 && other < k) continue;
        if (!(lambda[multipliers_.friction_normal[k]] > 0))
          ++open;
        else if (friction_slips(k, lambda, 1e-6))
          ++slip;
        else
          ++stick;
      }
    }
    out[c].rows = comm_.sum(rows);
    out[c].active = comm_.sum(active);
    out[c].normal_force = sum(force);
    out[c].area = sum(area);
    out[c].max_penetration = comm_.max(penetration);
    out[c].friction = comm_.sum(friction_rows) > 0;
    if (out[c].friction) {
      out[c].tangential_force = sum(tangential);
      out[c].open = comm_.sum(open), out[c].stick = comm_.sum(stick), out[c].slip = comm_.sum(slip);
    }
  }
  // The resultants: the condition of each row and lambda spread to the ranks that touch it,
  // then per subdomain the sums over the entries on the key side, added in subdomain order
  // (slots 0 .. conditions - 1: the normal rows; conditions .. 2 conditions - 1: friction).
  Vec cond = Vec::Constant(multipliers_.layout.n_ext(), -1.0);
  for (int k = 0; k < n_own; ++k) {
    if (multipliers_.kind[k] == MultiplierKind::contact)
      cond[k] = multipliers_.contact_condition[k];
    if (multipliers_.kind[k] == MultiplierKind::friction)
      cond[k] = conditions + multipliers_.contact_condition[k];
  }
  multipliers_.layout.forward(cond.data());
  multipliers_.gather(lambda);
  const size_t per = 6 * static_cast<size_t>(conditions);
  std::vector<double> part(per * layout_.num_subdomains, 0.0);
  for (size_t s = 0; s < subs_.size(); ++s) {
    const int dpn = subs_[s]->dofs_per_node();
    double* f = &part[per * subs_[s]->id()];
    for (const auto& r : multipliers_.rows[s]) {
      const int c = static_cast<int>(cond[r.k]);
      if (c >= 0 && c < 2 * conditions && r.side > 0)
        f[3 * c + r.dof % dpn] -= r.value * multipliers_.ext_in[r.k];
    }
  }
  if (comm_.size() > 1)
    MPI_Allreduce(MPI_IN_PLACE, part.data(), static_cast<int>(part.size()), MPI_DOUBLE, MPI_SUM,
                  comm_.raw());
  for (int s = 0; s < layout_.num_subdomains; ++s)
    for (int c = 0; c < conditions; ++c)
      for (int d = 0; d < 3; ++d) {
        out[c].resultant[d] += part[per * s + 3 * c + d];
        out[c].tangential[d] += part[per * s + 3 * (conditions + c) + d];
      }
  return out;
}

DualProblem::ContactFields DualProblem::contact_fields(const std::vector<Vec>& u,
                                                       const Vec& lambda) {
  // The per-row values of contact_data (the same formulas), spread to the ranks that touch the
  // rows and put on the node each row is keyed by.
  const ContactRowValues v = contact_row_values(u, lambda);
  const int n_ext = multipliers_.layout.n_ext();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Vec p = Vec::Constant(n_ext, nan), t = p, sl = p, st = p;
  const int n_own = multipliers_.layout.n_owned();
  for (int k = 0; k < n_own; ++k)
    if (multipliers_.kind[k] == MultiplierKind::contact)
      p[k] = v.pressure[k], t[k] = v.tangential[k], sl[k] = v.slip[k], st[k] = v.state[k];
  for (Vec* f : {&p, &t, &sl, &st}) multipliers_.layout.forward(f->data());
  ContactFields out;
  const size_t ns = subs_.size();
  out.pressure.resize(ns), out.tangential.resize(ns), out.slip.resize(ns), out.state.resize(ns);
  for (size_t s = 0; s < ns; ++s) {
    const int dpn = subs_[s]->dofs_per_node(), nodes = subs_[s]->size() / dpn;
    for (auto* f : {&out.pressure, &out.tangential, &out.slip, &out.state})
      (*f)[s] = Vec::Constant(nodes, nan);
    std::vector<int> last(nodes, -1);  // a row has one entry per normal component
    for (const auto& r : multipliers_.rows[s]) {
      const int node = r.dof / dpn;
      if (!r.key || (std::isnan(p[r.k]) && std::isnan(st[r.k]))) continue;
      if (last[node] == r.k) continue;
      double& pv = out.pressure[s][node];
      if (!std::isnan(p[r.k]))  // rows of several conditions at one node add
        pv = std::isnan(pv) ? p[r.k] : pv + p[r.k];
      if (std::isnan(out.state[s][node])) {  // friction: the node's first row with it
        out.tangential[s][node] = t[r.k];
        out.slip[s][node] = sl[r.k];
        out.state[s][node] = st[r.k];
      }
      last[node] = r.k;
    }
  }
  return out;
}

std::shared_ptr<const qp::ConstraintSet> DualProblem::constraint_set() const {
  const int n = multipliers_.layout.n_owned();
  const double inf = std::numeric_limits<double>::infinity();
  Vec lower(n), upper(n);
  std::vector<qp::SeparableSet::Pair> discs;
  std::vector<double> radii;
  for (int k = 0; k < n; ++k) {
    const MultiplierKind kind = multipliers_.kind[k];
    lower[k] = kind == MultiplierKind::contact ? 0.0 : -inf;
    upper[k] = inf;
    if (kind != MultiplierKind::friction) continue;
    const double bound = multipliers_.friction_bound[k];
    const int other = multipliers_.friction_partner[k];
    if (other < 0) {  // 2D: an interval
      lower[k] = -bound, upper[k] = bound;
    } else if (k < other) {  // 3D: one disc per node's pair
      discs.push_back({k, other});
      radii.push_back(bound);
    }
  }
  if (!has_friction()) return std::make_shared<qp::LowerBounds>(std::move(lower));
  if (layout_.dim == 2) return std::make_shared<qp::BoxBounds>(std::move(lower), std::move(upper));
  Vec r = Eigen::Map<const Vec>(radii.data(), static_cast<Eigen::Index>(radii.size()));
  return std::make_shared<qp::SeparableSet>(std::move(lower), std::move(upper), std::move(discs),
                                            Vec::Zero(2 * r.size()), std::move(r));
}

std::pair<double, double> DualProblem::update_coulomb_bounds(const Vec& lambda, bool apply) {
  const int n = multipliers_.layout.n_owned();
  Vec change = Vec::Zero(n), value = Vec::Zero(n);
  for (int k = 0; k < n; ++k) {
    const double mu = multipliers_.friction_mu[k];
    if (multipliers_.kind[k] != MultiplierKind::friction || mu < 0) continue;
    const double bound = mu * std::max(lambda[multipliers_.friction_normal[k]], 0.0);
    const double old = multipliers_.friction_bound[k];
    change[k] = std::isfinite(old) ? bound - old : bound;  // the first step: all of it
    value[k] = bound;
    if (apply) multipliers_.friction_bound[k] = bound;
  }
  return {std::sqrt(dot(change, change)), std::sqrt(dot(value, value))};
}

bool DualProblem::friction_slips(int k, const Vec& lambda, double rel_tol) const {
  const int other = multipliers_.friction_partner[k];
  const double t = other < 0 ? std::abs(lambda[k]) : std::hypot(lambda[k], lambda[other]);
  return !(t < (1 - rel_tol) * multipliers_.friction_bound[k]);
}

DualProblem::FrictionSummary DualProblem::friction_summary(const Vec& lambda,
                                                           double rel_tol) const {
  FrictionSummary f;
  Vec force = Vec::Zero(lambda.size());
  long long stick = 0, slip = 0;
  for (Eigen::Index k = 0; k < lambda.size(); ++k)
    if (multipliers_.kind[k] == MultiplierKind::friction) {
      const int other = multipliers_.friction_partner[k];
      if (other < 0) force[k] = -multipliers_.contact_scale[k] * lambda[k];  // 2D: along t
      if (other >= 0 && other < k) continue;  // 3D: a node's pair once
      if (friction_slips(static_cast<int>(k), lambda, rel_tol))
        ++slip;
      else
        ++stick;
    }
  f.tangential_force = sum(force);
  f.stick = comm_.sum(stick);
  f.slip = comm_.sum(slip);
  return f;
}

std::vector<DualProblem::Vec> DualProblem::contact_forces(const Vec& lambda) {
  multipliers_.gather(lambda);
  std::vector<Vec> out(subs_.size());
  for (size_t s = 0; s < subs_.size(); ++s) {
    out[s] = Vec::Zero(subs_[s]->size());
    for (const auto& r : multipliers_.rows[s])
      if (r.side != 0) out[s][r.dof] -= r.value * multipliers_.ext_in[r.k];
  }
  return out;
}

std::vector<DualProblem::Vec> DualProblem::contact_gap_field(const std::vector<Vec>& u) {
  Vec bu;
  apply_B(u, bu);
  const int n_own = multipliers_.layout.n_owned();
  // NaN on every row but the normal contact rows (friction rows also carry a side).
  Vec rem = Vec::Constant(multipliers_.layout.n_ext(), std::numeric_limits<double>::quiet_NaN());
  for (int k = 0; k < n_own; ++k)
    if (multipliers_.kind[k] == MultiplierKind::contact)
      rem[k] = (multipliers_.rhs[k] - bu[k]) /
               (multipliers_.contact_scale[k] * multipliers_.contact_weight[k]);
  multipliers_.layout.forward(rem.data());
  std::vector<Vec> out(subs_.size());
  for (size_t s = 0; s < subs_.size(); ++s) {
    const int dpn = subs_[s]->dofs_per_node();
    out[s] = Vec::Constant(subs_[s]->size() / dpn, std::numeric_limits<double>::quiet_NaN());
    for (const auto& r : multipliers_.rows[s])
      if (r.key && !std::isnan(rem[r.k])) {  // the smallest remaining gap of a node's rows
        double& g = out[s][r.dof / dpn];
        g = std::isnan(g) ? rem[r.k] : std::min(g, rem[r.k]);
      }
  }
  return out;
}

}  // namespace htfeti
