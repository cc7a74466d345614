#include "engine/coordination/clash_keys.h"

#include <utility>

namespace mktree::coordination {

uint64_t StableHash(std::string_view bytes) {
  uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  h ^= h >> 30;
  h *= 0xbf58476d1ce4e5b9ull;
  h ^= h >> 27;
  h *= 0x94d049bb133111ebull;
  h ^= h >> 31;
  return h;
}

std::string Hex64(uint64_t v) {
  static const char* digits = "0123456789abcdef";
  std::string s(16, '0');
  for (int i = 15; i >= 0; --i, v >>= 4) s[i] = digits[v & 15];
  return s;
}

std::string_view SourceBaseName(std::string_view source) {
  const size_t slash = source.find_last_of("/\\");
  return slash == std::string_view::npos ? source : source.substr(slash + 1);
}

std::string_view AttributeValue(const ObjectRecord& object, std::string_view key) {
  for (const ObjectAttribute& a : object.attributes)
    if (a.key == key) return a.value;
  return {};
}

std::string StableIdentity(std::string_view source, std::string_view global_id, std::string_view name) {
  std::string s(SourceBaseName(source));
  s += '|';
  if (!global_id.empty()) {
    s += global_id;
  } else {
    s += "name=";
    s += name;
  }
  return s;
}

std::string StableIdentity(const ObjectRecord& o) {
  return StableIdentity(o.source, AttributeValue(o, "ifc_global_id"), o.name);
}

std::string ClashKey(std::string_view test, std::string_view a, std::string_view b) {
  if (b < a) std::swap(a, b);
  // Lengths first, so that no two different triples give the same bytes.
  std::string bytes =
      std::to_string(test.size()) + ':' + std::to_string(a.size()) + ':' + std::to_string(b.size()) + ':';
  bytes.append(test).append(a).append(b);
  return Hex64(StableHash(bytes));
}

}  // namespace mktree::coordination
