// The wall clock the clash stages report their seconds with (ClashStats' broad, read and narrow seconds).
#pragma once

#include <chrono>

namespace mktree::clash {

using StageClock = std::chrono::steady_clock;

inline double SecondsSince(StageClock::time_point t) {
  return std::chrono::duration<double>(StageClock::now() - t).count();
}

}  // namespace mktree::clash
