// Resident memory of this process, for the report's per-phase peaks and for the memory check
// before the large allocations (Linux /proc; 0 where it cannot be read).
#pragma once

#include <mpi.h>

#include <cstdio>
#include <cstring>

namespace htfeti {

/// Value of a "Key:   N kB" line of /proc/self/status (VmHWM: peak resident, VmRSS: current) or
/// of /proc/meminfo (MemAvailable), in MiB.
inline double proc_status_mb(const char* file, const char* key) {
  std::FILE* f = std::fopen(file, "r");
  if (!f) return 0;
  char line[256];
  double kb = 0;
  const size_t n = std::strlen(key);
  while (std::fgets(line, sizeof line, f))
    if (std::strncmp(line, key, n) == 0 && line[n] == ':') {
      std::sscanf(line + n + 1, "%lf", &kb);
      break;
    }
  std::fclose(f);
  return kb / 1024.0;
}

/// Peak resident memory of this process so far (MiB).
inline double peak_rss_mb() { return proc_status_mb("/proc/self/status", "VmHWM"); }
/// Memory the kernel can still give without swapping (MiB).
inline double available_memory_mb() { return proc_status_mb("/proc/meminfo", "MemAvailable"); }
/// Resident memory of this process now (MiB).
inline double current_rss_mb() { return proc_status_mb("/proc/self/status", "VmRSS"); }

/// The ranks of comm on this machine (MPI_COMM_TYPE_SHARED). Collective.
inline int ranks_on_this_machine(MPI_Comm comm) {
  MPI_Comm node;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  int n = 1;
  MPI_Comm_size(node, &n);
  MPI_Comm_free(&node);
  return n;
}

/// The memory this rank may still take (MiB): the machine's available memory, and with a limit
/// of limit_mb per machine (> 0) shared by machine_ranks ranks, at most the rank's share of the
/// limit less what the rank holds now.
inline double usable_memory_mb(double limit_mb, int machine_ranks) {
  const double available = available_memory_mb();
  if (limit_mb <= 0) return available;
  const double share = limit_mb / machine_ranks - current_rss_mb();
  return available < share ? available : share;
}

}  // namespace htfeti
