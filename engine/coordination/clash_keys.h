// Stable identities of objects and stable keys of clashes (docs/clash_workflow.md, "Keys"): texts and
// hashes that depend on what the input says an object is (its source model's file name, its IFC GlobalId
// or its name), never on ids, load order or which side of a test it is on. Thread safety: pure functions.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "mktree/database.h"

namespace mktree::coordination {

// 64 bits of FNV-1a over the bytes, then a finaliser that spreads them (splitmix64's).
uint64_t StableHash(std::string_view bytes);
// 16 lower-case hex digits.
std::string Hex64(uint64_t v);

// The source's file name without its folders ("models/duplex.ifc" -> "duplex.ifc"; either separator).
std::string_view SourceBaseName(std::string_view source);
// The object's first value of attribute `key`, "" when none.
std::string_view AttributeValue(const ObjectRecord& object, std::string_view key);

// "<source file name>|<GlobalId>" when the object has an ifc_global_id, else "<source file
// name>|name=<name>".
std::string StableIdentity(std::string_view source, std::string_view global_id, std::string_view name);
std::string StableIdentity(const ObjectRecord& object);

// The clash key of `test` over two objects' stable identities, in either order: Hex64 of the hash of the
// test's name and the two identities sorted.
std::string ClashKey(std::string_view test, std::string_view identity_a, std::string_view identity_b);

}  // namespace mktree::coordination
