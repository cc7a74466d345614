#include "engine/store_format/leaf_claims.h"

#include <cstdlib>
#include <new>

namespace mktree {

struct LeafClaims::State {
  struct Free {
    void operator()(uint64_t* p) const { std::free(p); }
  };
  State(uint64_t leaves_in, uint64_t objects_in)
      : leaves(leaves_in),
        objects(objects_in),
        leaf(std::make_unique<std::atomic<uint8_t>[]>(leaves_in)),
        id_bits(static_cast<uint64_t*>(std::calloc((objects_in + 63) / 64 + 1, sizeof(uint64_t)))) {
    if (!id_bits) throw std::bad_alloc();
    for (uint64_t l = 0; l < leaves; ++l) leaf[l].store(kUnclaimed, std::memory_order_relaxed);
  }
  static constexpr uint8_t kUnclaimed = 0, kClaimed = 1, kRefused = 2;
  const uint64_t leaves, objects;
  std::unique_ptr<std::atomic<uint8_t>[]> leaf;    // written under mu_
  std::unique_ptr<uint64_t, Free> id_bits;         // under mu_: the ids claimed
  std::unordered_map<uint32_t, uint64_t> refused;  // under mu_: refused leaf -> an id claimed before
};

LeafClaims::LeafClaims() = default;
LeafClaims::LeafClaims(const LeafClaims&) {}

LeafClaims& LeafClaims::operator=(const LeafClaims&) {
  std::lock_guard<std::mutex> lock(mu_);
  if (State* s = state_.exchange(nullptr)) retired_.emplace_back(s);
  return *this;
}

LeafClaims::~LeafClaims() { delete state_.load(); }

bool LeafClaims::Claimed(uint32_t leaf) const {
  const State* s = state_.load(std::memory_order_acquire);
  return s != nullptr && leaf < s->leaves && s->leaf[leaf].load(std::memory_order_acquire) == State::kClaimed;
}

LeafClaims::State* LeafClaims::StateFor(uint64_t leaves, uint64_t objects) const {
  State* s = state_.load(std::memory_order_relaxed);
  if (s != nullptr && s->leaves == leaves && s->objects == objects) return s;
  // Another table's sizes (assigned in place): start again, keeping the old state for lock-free readers.
  auto fresh = std::make_unique<State>(leaves, objects);
  if (s != nullptr) retired_.emplace_back(s);
  s = fresh.release();
  state_.store(s, std::memory_order_release);
  return s;
}

uint64_t LeafClaims::Claim(uint32_t leaf, uint64_t leaves, uint64_t objects,
                           std::span<const uint32_t> ids) const {
  std::lock_guard<std::mutex> lock(mu_);
  State* s = StateFor(leaves, objects);
  if (leaf >= s->leaves) return kNone;  // no such leaf: the caller refuses it anyway
  std::atomic<uint8_t>& state = s->leaf[leaf];
  const uint8_t now = state.load(std::memory_order_relaxed);
  if (now == State::kClaimed) return kNone;
  if (now == State::kRefused) return s->refused.at(leaf);
  uint64_t* bits = s->id_bits.get();
  for (uint32_t id : ids) {
    if (id >= s->objects) return kNone;  // out of range: the caller refuses it anyway
    if (bits[id >> 6] & (uint64_t{1} << (id & 63))) {
      s->refused.emplace(leaf, id);
      state.store(State::kRefused, std::memory_order_release);
      return id;
    }
  }
  for (uint32_t id : ids) bits[id >> 6] |= uint64_t{1} << (id & 63);
  state.store(State::kClaimed, std::memory_order_release);
  return kNone;
}

}  // namespace mktree
