// SHA-1 (FIPS 180-4) of a byte string: the hash of the name-based UUIDs (uuid_v5.h) that give BCF topics
// and viewpoints identifiers that do not change between runs. Not for security.
//
// Thread safety: a pure function.
#pragma once

#include <array>
#include <cstdint>
#include <string_view>

namespace mktree {

std::array<uint8_t, 20> Sha1(std::string_view bytes);

}  // namespace mktree
