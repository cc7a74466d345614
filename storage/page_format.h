// A page is exactly MemPage bytes: a fixed page header (storage/page_codec.h), then a slice of a payload.
#pragma once

#include <cstdint>

namespace mktree {

inline constexpr uint64_t kPageHeaderBytes = 32;  // see storage/page_codec.h for its fields

// Payload bytes one page carries.
inline constexpr uint64_t PagePayloadCapacity(uint64_t mem_page) { return mem_page - kPageHeaderBytes; }

}  // namespace mktree
