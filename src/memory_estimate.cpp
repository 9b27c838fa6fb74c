#include "htfeti/memory_estimate.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "htfeti/feti/subdomain.hpp"
#include "htfeti/parallel/memory.hpp"

namespace htfeti {

namespace {

constexpr double kMiB = 1048576.0;
// Largest sample subdomain that is assembled and analysed (unknowns); larger ones are judged by
// the lower bound alone.
constexpr double kMaxSampleUnknowns = 4e6;

// Stored nonzeros per row of the lower triangle of K, at least (interior nodes of the sparsest
// element type of the dimension: tri3 has 7 neighbours and tet4 about 15, counting the node).
double lower_nonzeros_per_row(const Physics& ph) {
  const double nodes = ph.dim == 2 ? 7.0 : 15.0;
  return 0.5 * (nodes * ph.dofs_per_node() + 1);
}

std::string gb(double mb) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f GB", mb / 1024.0);
  return buf;
}

}  // namespace

MemoryEstimate estimate_memory(const Model& model, const FetiOptions& options, const Comm& comm) {
  MemoryEstimate e;
  const FetiLayout layout = model.layout();
  const auto [c0, c1] = layout.cluster_range(comm.rank(), comm.size());
  if (c0 == c1) return e;
  const int s0 = layout.cluster_first[c0], s1 = layout.cluster_first[c1];
  const double share = static_cast<double>(s1 - s0) / model.num_subdomains();
  const double unknowns = static_cast<double>(model.primal_dimension()) * share;
  const double per_subdomain = unknowns / (s1 - s0);
  const Physics& ph = model.physics();
  e.vectors_mb = unknowns * 8.0 * (ph.kernel_dimension() + 8) / kMiB;
  const double lower_nnz = unknowns * lower_nonzeros_per_row(ph);
  e.matrices_mb = lower_nnz * 12.0 / kMiB;
  e.factors_mb = lower_nnz * 8.0 / kMiB;  // L has at least the nonzeros of K's lower triangle
  if (per_subdomain > kMaxSampleUnknowns) return e;
  // Sample: the rank's first subdomain, assembled and analysed with the ordering in effect.
  SubdomainInput in = model.input(s0);
  const double n = static_cast<double>(in.system.f.size());
  if (n == 0) return e;
  const double k_bytes = 12.0 * static_cast<double>(in.system.K.nonZeros());
  const Ordering ordering = options.ordering == Ordering::automatic
                                ? (layout.dim == 3 ? Ordering::metis : Ordering::amd)
                                : options.ordering;
  Subdomain sample(std::move(in.system));
  const double f_bytes = static_cast<double>(sample.symbolic_factor_bytes(ordering));
  e.matrices_mb = std::max(e.matrices_mb, k_bytes / n * unknowns / kMiB);
  e.factors_mb = std::max(e.factors_mb, f_bytes / n * unknowns / kMiB);
  e.sampled = true;
  return e;
}

MemoryEstimate check_memory(const Model& model, const FetiOptions& options, const Comm& comm) {
  // The lower bound first, everywhere (nothing is assembled); then the sample where the bound
  // fits. Both are summed over the ranks of each machine.
  MPI_Comm node;
  MPI_Comm_split_type(comm.raw(), MPI_COMM_TYPE_SHARED, comm.rank(), MPI_INFO_NULL, &node);
  std::string error;
  MemoryEstimate e;
  try {
    e = estimate_memory(model, options, comm);
  } catch (const std::bad_alloc&) {
    error = "out of memory while estimating the memory needed";
  } catch (const std::exception& ex) {
    error = ex.what();
  }
  double mine[4] = {e.peak_mb(), e.factors_mb, e.matrices_mb, e.vectors_mb}, sum[4];
  MPI_Allreduce(mine, sum, 4, MPI_DOUBLE, MPI_SUM, node);
  double available = available_memory_mb();
  MPI_Allreduce(MPI_IN_PLACE, &available, 1, MPI_DOUBLE, MPI_MIN, node);
  int node_ranks = 1;
  MPI_Comm_size(node, &node_ranks);
  MPI_Comm_free(&node);
  if (error.empty() && available > 0 && sum[0] > available)
    error = "the problem does not fit in memory: estimated " + gb(sum[0]) + " on " +
            std::to_string(node_ranks) + " rank(s) of this machine (factors " + gb(sum[1]) +
            ", matrices " + gb(sum[2]) + ", vectors " + gb(sum[3]) + "), available " +
            gb(available) +
            "; use fewer unknowns, more machines, or --no-memory-check to try anyway";
  comm.agree(error, true);
  return e;
}

}  // namespace htfeti
