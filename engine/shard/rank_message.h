// The byte messages ranks send each other (engine/shard/rank_exchange.h): fixed-width values and
// length-prefixed strings appended to a buffer, and read back in the same order. Both ends are processes of
// one build on one kind of machine, so values go in the host's byte order.
// REQUIRES (Get, GetString): the buffer holds what is read, as the sender wrote it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace mktree {

template <typename T>
void Put(std::vector<uint8_t>* b, const T& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  const size_t n = b->size();
  b->resize(n + sizeof(T));
  std::memcpy(b->data() + n, &v, sizeof(T));
}
template <typename T>
T Get(const std::vector<uint8_t>& b, size_t* at) {
  T v;
  std::memcpy(&v, b.data() + *at, sizeof(T));
  *at += sizeof(T);
  return v;
}
inline void PutString(std::vector<uint8_t>* b, const std::string& s) {
  Put<uint64_t>(b, s.size());
  b->insert(b->end(), s.begin(), s.end());
}
inline std::string GetString(const std::vector<uint8_t>& b, size_t* at) {
  const uint64_t n = Get<uint64_t>(b, at);
  std::string s(reinterpret_cast<const char*>(b.data() + *at), n);
  *at += n;
  return s;
}

}  // namespace mktree
