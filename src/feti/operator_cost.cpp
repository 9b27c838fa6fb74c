// The automatic dual operator's cost model (operator_cost.hpp). One evaluation: the symbolic
// analysis of kCostSamples subdomains (an ordering of each: METIS in 3D), three reductions.
#include "htfeti/feti/operator_cost.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>
#include <vector>

#include "htfeti/clock.hpp"
#include "htfeti/feti/dual_problem.hpp"
#include "htfeti/feti/input.hpp"
#include "htfeti/feti/subdomain.hpp"
#include "htfeti/model/model.hpp"
#include "htfeti/parallel/comm.hpp"

namespace htfeti {

OperatorCostConstants OperatorCostConstants::fitted() {
  OperatorCostConstants c;
  // bench/operator_cost.py --fit on this machine (2-core AMD EPYC guest, one thread; bench/
  // results/operator_cost.json): least squares of the relative errors over its TFETI cases.
  c.sweep_per_byte = 1.04e-10;
  c.per_supernode = 6.13e-7;
  c.packed_per_byte = 1.61e-10;
  c.factor_per_flop = 2.09e-10;
  c.per_unknown = 2.92e-6;
  c.dense_per_flop = 1.24e-10;
  c.explicit_per_unknown = 1.33e-6;
  return c;
}

MultiplierCount count_multipliers(const SubdomainInput& in, int dofs_per_node) {
  const int nodes = in.sharing.num_nodes();
  // The dofs B~ touches: every dof of a shared node or of a node in a contact row, and the
  // Dirichlet dofs.
  std::vector<char> whole(nodes, 0);
  double multipliers = 0;
  for (int k = 0; k < nodes; ++k)
    if (in.sharing.num_copies(k) > 1) {
      whole[k] = 1;
      multipliers += static_cast<double>(in.sharing.num_copies(k) - 1) * dofs_per_node;
    }
  // A contact row is given to every node of it: count each row once (its key node and its
  // condition), with its tangential rows when it has friction.
  std::set<std::pair<long long, int>> rows;
  for (const ContactRow& r : in.contact) {
    whole[r.node] = 1;
    if (!rows.insert({r.node_a, r.condition}).second) continue;
    multipliers += 1;
    if (r.slip_bound >= 0 || r.friction_coefficient >= 0)
      multipliers += dofs_per_node == 2 ? 1 : r.tangent_rows;
  }
  double touched = 0;
  for (int k = 0; k < nodes; ++k) touched += whole[k] ? dofs_per_node : 0;
  for (const DirichletDof& d : in.dirichlet) touched += whole[d.node] ? 0 : 1;
  return {multipliers + static_cast<double>(in.dirichlet.size()), touched};
}

SubdomainCostSample sample_subdomain_cost(SubdomainInput in, int dofs_per_node, Ordering ordering) {
  SubdomainCostSample s;
  s.unknowns = static_cast<double>(in.system.f.size());
  const MultiplierCount count = count_multipliers(in, dofs_per_node);
  s.multipliers = count.multipliers;
  s.interface_dofs = count.interface_dofs;
  Subdomain sub(std::move(in.system));
  const SparseCholesky::SymbolicStats st = sub.symbolic_stats(ordering);
  s.factor_values = st.values;
  s.factor_supernodes = st.supernodes;
  s.factor_flops = st.flops;
  return s;
}

OperatorCost operator_cost(const SubdomainCostSample& m, int samples, bool contact,
                           double value_bytes, const OperatorCostConstants& c) {
  OperatorCost o;
  o.samples = samples;
  o.mean = m;
  o.expected_applications = contact ? kExpectedApplicationsContact : kExpectedApplicationsLinear;
  o.implicit_setup = c.factor_per_flop * m.factor_flops + c.per_unknown * m.unknowns;
  o.implicit_per_F =
      c.sweep_per_byte * 16.0 * m.factor_values + c.per_supernode * m.factor_supernodes;
  o.explicit_setup = o.implicit_setup + c.dense_per_flop * std::pow(m.interface_dofs, 3.0) +
                     c.explicit_per_unknown * m.unknowns;
  o.explicit_per_F = c.packed_per_byte * value_bytes * m.multipliers * (m.multipliers + 1) / 2;
  const double saved = o.implicit_per_F - o.explicit_per_F;
  if (saved > 0) o.break_even = (o.explicit_setup - o.implicit_setup) / saved;
  return o;
}

std::optional<OperatorCost> estimate_operator_cost(const Model& model, const FetiOptions& options,
                                                   const Comm& comm) {
  const double t0 = seconds_now();
  const FetiLayout layout = model.layout();
  const int S = model.num_subdomains();
  std::vector<int> ids{0, S / 2, S - 1};
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  const Ordering ordering = resolve_ordering(options.ordering, layout.dim, false);
  // Each sample counted on the rank holding it, in its own slot: the sums below add one
  // nonzero per slot, so every rank gets the same values whatever the number of ranks.
  constexpr int kFields = 6;
  std::vector<double> slots(kCostSamples * kFields, 0.0);
  // The samples of a rank side by side on its threads (assembly and analysis; METIS's random
  // numbers are per thread, see sparse_cholesky.cpp): 0.15-0.17 -> 0.09-0.13 s on the
  // METIS-split 40^3 cube, two threads (measured while METIS calls were still serialized).
  int failed = 0;
  const int count = static_cast<int>(ids.size());
#pragma omp parallel for schedule(dynamic) reduction(max : failed)
  for (int k = 0; k < count; ++k) {
    if (layout.rank_of_subdomain(ids[k], comm.size()) != comm.rank()) continue;
    try {
      const SubdomainCostSample s =
          sample_subdomain_cost(model.input(ids[k]), layout.dofs_per_node, ordering);
      const double v[kFields] = {s.unknowns,      s.multipliers,       s.interface_dofs,
                                 s.factor_values, s.factor_supernodes, s.factor_flops};
      std::copy(v, v + kFields, slots.begin() + static_cast<long>(k) * kFields);
    } catch (...) {
      failed = 1;
    }
  }
  if (comm.max(static_cast<double>(failed)) > 0) return std::nullopt;
  comm.sum_in_place(slots.data(), static_cast<int>(slots.size()));
  SubdomainCostSample mean;
  double* fields[kFields] = {&mean.unknowns,      &mean.multipliers,       &mean.interface_dofs,
                             &mean.factor_values, &mean.factor_supernodes, &mean.factor_flops};
  const double n = static_cast<double>(ids.size());
  for (int f = 0; f < kFields; ++f) {
    double sum = 0;
    for (size_t k = 0; k < ids.size(); ++k) sum += slots[k * kFields + f];
    *fields[f] = sum / n;
  }
  const double value_bytes = options.explicit_precision == Precision::single ? 4.0 : 8.0;
  OperatorCost cost =
      operator_cost(mean, static_cast<int>(ids.size()), model.has_contact(), value_bytes);
  cost.seconds = seconds_now() - t0;
  return cost;
}

}  // namespace htfeti
