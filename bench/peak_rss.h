// The peak RSS of this process from the kernel's VmHWM, for benchmarks whose children measure themselves.
// A parent's wait4 rusage does not do: Linux counts in a child's ru_maxrss the resident pages it shared with
// its parent until its exec (fork), or whose address space it borrowed (posix_spawn's vfork), so a child of
// a bench that holds a scene reports the bench's pages too. VmHWM belongs to the address space, which an
// exec starts afresh.
#pragma once

#include <cstdio>

namespace mktree::bench {

// MiB; 0 where /proc is not there.
inline double PeakRssMiB() {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (!f) return 0;
  char line[256];
  double kib = 0;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "VmHWM: %lf kB", &kib) == 1) break;
  std::fclose(f);
  return kib / 1024;
}

}  // namespace mktree::bench
