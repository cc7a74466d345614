#include "tools/progress.h"

#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>

namespace mktree::tools {

Progress::Progress(bool quiet) : quiet_(quiet), terminal_(::isatty(2) != 0) {}

void Progress::Update(const std::string& step, uint64_t done, uint64_t total) {
  if (quiet_) return;
  const auto now = std::chrono::steady_clock::now();
  const bool new_step = step != step_;
  if (new_step) {
    Done();
    step_ = step;
    step_start_ = now;
  }
  const bool finished = total != 0 && done >= total;
  const auto every = terminal_ ? std::chrono::milliseconds(100) : std::chrono::milliseconds(5000);
  if (!new_step && !finished && now - last_ < every) return;
  last_ = now;
  const double secs = std::chrono::duration<double>(now - step_start_).count();
  if (terminal_) {
    if (total) {
      const int width = 30;
      const int filled = static_cast<int>(width * static_cast<double>(done) / static_cast<double>(total));
      std::string bar(filled, '#');
      bar.resize(width, '.');
      std::fprintf(stderr, "\r%-20s [%s] %3.0f%%  %llu/%llu  %.1fs", step.c_str(), bar.c_str(),
                   100.0 * static_cast<double>(done) / static_cast<double>(total),
                   static_cast<unsigned long long>(done), static_cast<unsigned long long>(total), secs);
    } else {
      std::fprintf(stderr, "\r%-20s %llu  %.1fs", step.c_str(), static_cast<unsigned long long>(done), secs);
    }
  } else {
    if (total)
      std::fprintf(stderr, "%s: %llu/%llu (%.0f%%) %.1fs\n", step.c_str(),
                   static_cast<unsigned long long>(done), static_cast<unsigned long long>(total),
                   100.0 * static_cast<double>(done) / static_cast<double>(total), secs);
    else
      std::fprintf(stderr, "%s: %llu %.1fs\n", step.c_str(), static_cast<unsigned long long>(done), secs);
  }
}

void Progress::Done() {
  if (!quiet_ && terminal_ && !step_.empty()) std::fprintf(stderr, "\n");
  step_.clear();
}

uint64_t PeakRssBytes() {
  struct rusage ru {};
  ::getrusage(RUSAGE_SELF, &ru);
  return static_cast<uint64_t>(ru.ru_maxrss) * 1024;
}

std::string HumanBytes(uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = static_cast<double>(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) {
    v /= 1024;
    ++u;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, u == 0 ? "%.0f %s" : "%.1f %s", v, units[u]);
  return buf;
}

}  // namespace mktree::tools
