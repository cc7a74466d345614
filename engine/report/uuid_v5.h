// Name-based UUIDs (RFC 4122 §4.3, version 5: SHA-1): the same namespace and name give the same UUID in
// every run and on every machine, so a BCF topic exported again keeps its GUID and updates the topic a BIM
// tool already holds instead of adding a second one.
//
// Thread safety: pure functions.
#pragma once

#include <string>
#include <string_view>

namespace mktree {

// The UUID in its lower-case text form "xxxxxxxx-xxxx-5xxx-yxxx-xxxxxxxxxxxx". `name_space` is a UUID in
// text form (hyphens, either case); REQUIRES: it is one.
std::string UuidV5(std::string_view name_space, std::string_view name);

// RFC 4122's URL namespace, 6ba7b811-9dad-11d1-80b4-00c04fd430c8.
inline constexpr std::string_view kUuidUrlNamespace = "6ba7b811-9dad-11d1-80b4-00c04fd430c8";

}  // namespace mktree
