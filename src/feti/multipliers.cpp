// Multipliers (multipliers.hpp): the numbering of the rows of B~ and the exchange of dual
// vectors. number() runs once in DualProblem's setup (stage 2); the rest is the hot path.
#include "htfeti/feti/multipliers.hpp"

#include <mpi.h>

#include <algorithm>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>

#include "htfeti/errors.hpp"
#include "htfeti/parallel/key_numbering.hpp"

namespace htfeti {

std::vector<std::vector<Subdomain::BEntry>> Multipliers::number(
    const FetiLayout& fl, const Comm& c, std::vector<std::vector<LocalRow>>& local_rows,
    int first_subdomain) {
  comm = &c;
  const int P = c.size(), me = c.rank();
  const int nsub = static_cast<int>(local_rows.size());
  // Global numbering of the rows by key, owners, and the extended dual layout.
  std::vector<NumberingKey> keys;
  std::vector<int> key_owner;
  std::vector<const LocalRow*> key_row;
  // key_of[s][r]: the index in keys of subdomain s's row r (so that no row searches the keys).
  std::vector<std::vector<int>> key_of(nsub);
  {
    struct Entry {
      RowKey key;
      const LocalRow* row;
      int s, r;
    };
    std::vector<Entry> all;
    size_t total = 0;
    for (int s = 0; s < nsub; ++s) total += local_rows[s].size();
    all.reserve(total);
    keys.reserve(total), key_owner.reserve(total), key_row.reserve(total);
    for (int s = 0; s < nsub; ++s) {
      key_of[s].resize(local_rows[s].size());
      for (size_t r = 0; r < local_rows[s].size(); ++r)
        all.push_back({local_rows[s][r].key, &local_rows[s][r], s, static_cast<int>(r)});
    }
    // (Rows with equal keys are alike to the comparison, so which comes first does not depend
    // on what else an entry carries.)
    std::sort(all.begin(), all.end(), [](const Entry& x, const Entry& y) { return x.key < y.key; });
    for (size_t i = 0; i < all.size(); ++i) {
      if (i == 0 || all[i].key != all[i - 1].key) {
        keys.push_back(all[i].key);
        key_owner.push_back(fl.rank_of_subdomain(all[i].row->owner_subdomain, P));
        key_row.push_back(all[i].row);
      }
      key_of[all[i].s][all[i].r] = static_cast<int>(keys.size()) - 1;
    }
  }
  // Bucket position: per-node rows by their node, object rows after all nodes by cluster.
  const long long nodes = fl.num_nodes;
  const std::vector<long long> index = number_keys(
      c, keys, nodes + fl.num_clusters,
      [nodes](const NumberingKey& k) { return k[0] == 0 ? k[1] : nodes + k[1]; }, dimension);
  {
    std::vector<long long> touched(index);
    std::vector<int> owner(key_owner);
    std::vector<size_t> perm(index.size());
    std::iota(perm.begin(), perm.end(), 0);
    std::sort(perm.begin(), perm.end(), [&](size_t a, size_t b) { return index[a] < index[b]; });
    for (size_t i = 0; i < perm.size(); ++i)
      touched[i] = index[perm[i]], owner[i] = key_owner[perm[i]];
    layout = DualLayout(c, touched, owner);
  }
  const int n_ext = layout.n_ext(), n_own = layout.n_owned();
  owner_rank.assign(n_ext, me);
  kind.assign(n_own, MultiplierKind::gluing);
  rhs = Vec::Zero(n_own);
  contact_scale.assign(n_own, 1.0);
  contact_weight.assign(n_own, 1.0);
  contact_gap.assign(n_own, 0.0);
  contact_condition.assign(n_own, -1);
  contact_point.assign(n_own, {0, 0, 0});
  long long my_inequalities = 0, my_friction = 0;
  owner_cluster.assign(n_own, 0);
  std::vector<int> key_ext(keys.size());  // each key's extended index
  for (size_t i = 0; i < keys.size(); ++i) {
    const int k = key_ext[i] = layout.ext_index(index[i]);
    owner_rank[k] = key_owner[i];
    if (k < n_own) {
      const LocalRow& r = *key_row[i];
      owner_cluster[k] = fl.cluster_of(r.owner_subdomain);
      kind[k] = r.kind;
      rhs[k] = r.rhs;
      contact_scale[k] = r.scale;
      contact_weight[k] = r.weight;
      contact_gap[k] = r.gap;
      contact_condition[k] = r.kind == MultiplierKind::gluing || r.kind == MultiplierKind::dirichlet
                                 ? -1
                                 : r.condition;
      contact_point[k] = r.point;
      if (r.kind == MultiplierKind::contact) ++my_inequalities;
      if (r.kind == MultiplierKind::friction) ++my_friction;
    }
  }
  inequalities = c.sum(my_inequalities);
  friction_rows = c.sum(my_friction);
  pair_friction_rows(fl, keys, index, key_row);
  // Friction rows: per subdomain, (first entry of the row, its part of the bound); contact
  // rows: (first entry, its part of the contact area).
  std::vector<std::vector<std::pair<size_t, double>>> bound_part(nsub), area_part(nsub);
  rows.assign(nsub, {});
  // Per subdomain, independent: in parallel.
  RegionError failure;
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    try {
      auto& lr = local_rows[s];
      std::vector<std::pair<int, const LocalRow*>> ordered;
      ordered.reserve(lr.size());
      for (size_t r = 0; r < lr.size(); ++r) ordered.push_back({key_ext[key_of[s][r]], &lr[r]});
      // Rows in global order (the order of the ext indices of owned entries, then ghosts, is the
      // global order within each part; sort by global index for a fixed accumulation order).
      std::sort(ordered.begin(), ordered.end(), [&](const auto& x, const auto& y) {
        return layout.global(x.first) < layout.global(y.first);
      });
      size_t entries = 0;
      for (const auto& [k, r] : ordered) entries += r->entries.size();
      rows[s].reserve(entries);
      for (const auto& [k, r] : ordered) {
        const RowClass cls = r->kind != MultiplierKind::gluing ? RowClass::other
                             : r->key[0] == 0                  ? RowClass::node
                                                               : RowClass::object;
        const auto side = static_cast<std::int8_t>(r->side);
        if (r->kind == MultiplierKind::friction)
          bound_part[s].push_back({rows[s].size(), r->bound});
        if (r->kind == MultiplierKind::contact && r->area != 0.0)
          area_part[s].push_back({rows[s].size(), r->area});
        const auto key = static_cast<std::uint8_t>(r->key_node);
        for (const auto& [dof, v] : r->entries) rows[s].push_back({k, -1, dof, side, cls, key, v});
      }
      lr = {};
    } catch (const std::exception& e) {
      failure.record(e);
    }
  }
  failure.rethrow();
  local_rows = {};

  // Local numbering of the rows on each subdomain: its distinct multipliers by global index (not
  // extended index, whose owned/ghost split depends on the ranks), which fixes the summation
  // order of the dense blocks F_i. rows[s] is in that order already, a row's entries together.
  std::vector<std::vector<Subdomain::BEntry>> local_b(nsub);
  of_subdomain.assign(nsub, {});
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < nsub; ++s) {
    try {
      auto& mult = of_subdomain[s];
      local_b[s].reserve(rows[s].size());
      for (auto& r : rows[s]) {
        if (mult.empty() || mult.back() != r.k) mult.push_back(r.k);
        r.j = static_cast<int>(mult.size()) - 1;
        local_b[s].push_back({r.j, r.dof, r.value});
      }
    } catch (const std::exception& e) {
      failure.record(e);
    }
  }
  failure.rethrow();
  for (int s = 0; s < nsub; ++s)
    if (!std::is_sorted(of_subdomain[s].begin(), of_subdomain[s].end(),
                        [&](int a, int b) { return layout.global(a) <= layout.global(b); }))
      throw std::logic_error("Multipliers::number: a subdomain's rows are not in global order");
  // Ordered sums over subdomains (F, B u, d) and the work vectors.
  {
    std::vector<int> pk;
    std::vector<long long> pc;
    pair_first.assign(nsub + 1, 0);
    for (int s = 0; s < nsub; ++s) {
      for (int k : of_subdomain[s]) pk.push_back(k), pc.push_back(first_subdomain + s);
      pair_first[s + 1] = static_cast<int>(pk.size());
    }
    subdomain_sum = OrderedSum(c, layout, pk, pc, owner_rank);
    pairs = Vec::Zero(static_cast<int>(pk.size()));
    num_clusters = fl.num_clusters;
    partial_terms.assign(static_cast<size_t>(kDotsReserved) * fl.num_clusters, 0.0);
  }
  ext_in = Vec::Zero(n_ext);
  ext_out = Vec::Zero(n_ext);
  // The friction bounds and the contact areas summed over the copies of each node, in the fixed
  // order of the sums.
  auto sum_parts = [&](const std::vector<std::vector<std::pair<size_t, double>>>& parts,
                       MultiplierKind of, Vec& out) {
    pairs.setZero();
    for (int s = 0; s < nsub; ++s)
      for (const auto& [e, b] : parts[s]) pairs[pair_first[s] + rows[s][e].j] += b;
    combine_subdomains();
    for (int k = 0; k < n_own; ++k)
      if (kind[k] == of) out[k] = ext_out[k];
    pairs.setZero();
    ext_out.setZero();
  };
  friction_bound = Vec::Constant(n_own, std::numeric_limits<double>::infinity());
  if (friction_rows > 0) sum_parts(bound_part, MultiplierKind::friction, friction_bound);
  Vec area = Vec::Zero(n_own);
  if (inequalities > 0) sum_parts(area_part, MultiplierKind::contact, area);
  contact_area.assign(area.data(), area.data() + n_own);
  return local_b;
}

void Multipliers::pair_friction_rows(const FetiLayout& fl, const std::vector<RowKey>& keys,
                                     const std::vector<long long>& index,
                                     const std::vector<const LocalRow*>& key_row) {
  const int n_own = layout.n_owned();
  // Their normal row and (3D) their partner, found by key among the owned rows
  // (a node's contact and friction rows have the same owner).
  friction_mu.assign(n_own, -1.0);
  friction_normal.assign(n_own, -1);
  friction_partner.assign(n_own, -1);
  if (friction_rows > 0) {
    std::map<RowKey, int> owned;
    for (size_t i = 0; i < keys.size(); ++i) {
      const int k = layout.ext_index(index[i]);
      if (k < n_own && kind[k] != MultiplierKind::gluing && kind[k] != MultiplierKind::dirichlet)
        owned[keys[i]] = k;
    }
    for (const auto& [key, k] : owned) {
      if (kind[k] != MultiplierKind::friction) continue;
      friction_mu[k] = key_row[std::lower_bound(keys.begin(), keys.end(), key) - keys.begin()]->mu;
      auto normal = owned.find({key[0], key[1], 2, key[3], 0, 0});
      auto other = owned.find({key[0], key[1], 3, key[3], 1 - key[4], 0});
      if (normal == owned.end())
        throw std::logic_error("a friction row without its contact row on the same rank");
      friction_normal[k] = normal->second;
      if (fl.dim == 3 && key[4] != kSingleTangent) {
        if (other == owned.end()) throw std::logic_error("a 3D friction row without its partner");
        friction_partner[k] = other->second;
      }
    }
  }
}

void Multipliers::combine_row_entries(const std::vector<std::vector<double>>& per_entry) {
  pairs.setZero();
  for (size_t s = 0; s < rows.size(); ++s) {
    const auto& r = rows[s];
    const double* in = per_entry[s].data();
    for (size_t j = 0; j < r.size(); ++j) pairs[pair_first[s] + r[j].j] += in[j];
  }
  combine_subdomains();
}

double Multipliers::dot(const Vec& a, const Vec& b) const {
  const Vec* pa = &a;
  const Vec* pb = &b;
  double out;
  dots(1, &pa, &pb, &out);
  return out;
}

double Multipliers::sum(const Vec& v) const {
  const Vec* pa = &v;
  const Vec* none = nullptr;
  double out;
  dots(1, &pa, &none, &out);
  return out;
}

void Multipliers::dots(int count, const Vec* const* a, const Vec* const* b, double* out) const {
  // Per term, a partial sum per owner cluster in entry order; every cluster's partial sum is
  // non-zero on one rank only, so the one allreduce of all terms adds exact zeros; each term's
  // partial sums are then added in cluster order on every rank.
  const size_t nc = static_cast<size_t>(num_clusters), all = static_cast<size_t>(count) * nc;
  if (partial_terms.size() < all) partial_terms.resize(all);  // only beyond kDotsReserved terms
  std::fill_n(partial_terms.begin(), all, 0.0);
  for (int k = 0; k < count; ++k) {
    double* pk = partial_terms.data() + static_cast<size_t>(k) * nc;
    const Vec& ak = *a[k];
    if (b[k]) {
      const Vec& bk = *b[k];
      for (Eigen::Index i = 0; i < ak.size(); ++i) pk[owner_cluster[i]] += ak[i] * bk[i];
    } else {
      for (Eigen::Index i = 0; i < ak.size(); ++i) pk[owner_cluster[i]] += ak[i];
    }
  }
  if (comm->size() > 1)
    MPI_Allreduce(MPI_IN_PLACE, partial_terms.data(), static_cast<int>(all), MPI_DOUBLE, MPI_SUM,
                  comm->raw());
  for (int k = 0; k < count; ++k) {
    const double* pk = partial_terms.data() + static_cast<size_t>(k) * nc;
    double s = 0;
    for (size_t c = 0; c < nc; ++c) s += pk[c];
    out[k] = s;
  }
}

}  // namespace htfeti
