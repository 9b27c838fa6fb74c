// Resident memory of this process, for the report's per-phase peaks and for the memory check
// before the large allocations (Linux /proc; 0 where it cannot be read).
#pragma once

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

}  // namespace htfeti
