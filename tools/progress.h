// Progress reporting for long steps: a redrawn bar on a terminal, plain periodic lines otherwise,
// nothing with --quiet.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

namespace mktree::tools {

class Progress {
 public:
  explicit Progress(bool quiet);
  // `total` 0 means unknown (a count is shown instead of a bar).
  void Update(const std::string& step, uint64_t done, uint64_t total);
  // Ends the current line, if a bar is drawn.
  void Done();

 private:
  bool quiet_;
  bool terminal_;
  std::string step_;
  std::chrono::steady_clock::time_point last_;
  std::chrono::steady_clock::time_point step_start_;
};

// Peak resident set size of this process, in bytes.
uint64_t PeakRssBytes();
std::string HumanBytes(uint64_t bytes);

}  // namespace mktree::tools
