// A test's bounded-memory check: code run in a forked child, whose peak RSS (ru_maxrss) is its own and not
// the test program's (the child shares the parent's pages only until it writes them; the gtest parent is
// small).
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <functional>

namespace mktree::testing {

struct ChildRun {
  bool exited = false;    // false: killed, or the fork or wait failed
  int code = -1;          // its exit code: `body`'s return value
  uint64_t peak_rss = 0;  // bytes
};

// Runs `body` in a forked child (it exits with body's return value) and waits for it.
inline ChildRun RunForPeakRss(const std::function<int()>& body) {
  ChildRun run;
  const pid_t child = ::fork();
  if (child < 0) return run;
  if (child == 0) ::_exit(body());
  int status = 0;
  struct rusage ru {};
  if (::wait4(child, &status, 0, &ru) != child) return run;
  run.exited = WIFEXITED(status);
  run.code = run.exited ? WEXITSTATUS(status) : -1;
  run.peak_rss = static_cast<uint64_t>(ru.ru_maxrss) * 1024;
  return run;
}

}  // namespace mktree::testing
