// Exceptions never cross mktree's API (include/mktree/) or reach the CLI's main uncaught: the entry points
// run their bodies through Guarded, which turns an exception (std::bad_alloc under a memory limit,
// std::system_error when a thread cannot start, anything else) into a Status naming `context`.
#pragma once

#include <string_view>

#include "mktree/status.h"

namespace mktree {

// The Status for the exception being handled. REQUIRES: called inside a catch block.
Status StatusOfCurrentException(std::string_view context) noexcept;

// f(), or the Status of what it threw. F returns a Status or a Result<T>.
template <typename F>
auto Guarded(std::string_view context, F&& f) noexcept -> decltype(f()) {
  try {
    return f();
  } catch (...) {
    return StatusOfCurrentException(context);
  }
}

}  // namespace mktree
