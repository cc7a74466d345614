#include "engine/core/guarded.h"

#include <exception>
#include <new>
#include <string>

namespace mktree {

Status StatusOfCurrentException(std::string_view context) noexcept {
  try {
    try {
      throw;
    } catch (const std::bad_alloc&) {
      return Status::Internal(std::string(context) + ": out of memory");
    } catch (const std::exception& e) {
      return Status::Internal(std::string(context) + ": " + e.what());
    } catch (...) {
      return Status::Internal(std::string(context) + ": unknown exception");
    }
  } catch (...) {
    // The message itself could not be built: this one fits std::string's inline buffer.
    return Status::Internal("out of memory");
  }
}

}  // namespace mktree
