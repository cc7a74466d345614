// The top levels of a sharded store (docs/shards.md): a small kd-tree computed once from a sample of the
// objects' boxes, whose leaves are the shards. Each object goes to exactly one shard by a rule of its box
// alone (at each top node: the box's key along the node's axis below the cut goes to child 0, else to
// child 1), so any process that sees an object routes it the same way, without the rest of the scene.
#pragma once

#include <cstdint>
#include <vector>

#include "mktree/geometry.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

inline constexpr uint32_t kNoShard = 0xffffffffu;
// Shards a manifest may have at most: a bound for files read from disk.
inline constexpr uint32_t kMaxShards = 1u << 20;
// Objects in the sample at most. The cuts are sample quantiles: their rank error is about 1/sqrt(size)
// of the objects (0.2 %), which moves shard sizes, never correctness. 48 bytes an object: 12.6 MB on
// the one process (MPI: rank 0) that chooses the cuts.
inline constexpr uint64_t kShardSampleSize = uint64_t{1} << 18;

// A bottom-k sample: the objects with the smallest hashes of their ids. The same objects are chosen
// whatever the order the objects come in and however they are split between readers (samples merge), so
// the top levels do not depend on the number of processes that read the scene.
class ShardSample {
 public:
  struct Item {
    uint64_t hash = 0;
    ObjectId id = 0;
    Box3d box;
  };
  explicit ShardSample(uint64_t capacity = kShardSampleSize) : capacity_(capacity) {}
  void Add(ObjectId id, const Box3d& box);
  void Merge(const ShardSample& other);
  // The items, by id; from an rvalue, moved out (a sample is 64 bytes an item: a build's peak is near).
  std::vector<Item> Items() const&;
  std::vector<Item> Items() &&;
  uint64_t size() const { return heap_.size(); }

 private:
  uint64_t capacity_;
  std::vector<Item> heap_;  // max-heap on hash
};

// Which key of a box a top node compares with its cut.
enum class ShardKey : uint8_t { kMin = 0, kMax = 1 };

struct TopNode {
  uint8_t axis = 0;               // 0..2 (internal nodes)
  ShardKey key = ShardKey::kMin;  // box.min[axis] or box.max[axis]
  double cut = 0;                 // key < cut: child 0, else child 1
  uint32_t child[2] = {kNoShard, kNoShard};
  uint32_t shard = kNoShard;  // a leaf: its shard; internal: kNoShard
  bool is_leaf() const { return shard != kNoShard; }
};

struct TopLevels {
  std::vector<TopNode> nodes;  // preorder from the root, node 0; shards numbered left to right
  uint32_t shard_count = 0;

  // The shard of an object with world box `box`.
  uint32_t ShardOf(const Box3d& box) const;
  // Whether some box whose coordinates are each within `slack` of `box`'s routes to `shard`: a reader that
  // knows an object's box only rounded (a stored float32 record box) can skip the objects of other shards.
  bool CanRouteTo(const Box3d& box, double slack, uint32_t shard) const;
  // Structure check (a manifest read from disk): preorder tree, each shard a leaf exactly once, finite
  // cuts, axes 0..2. Corruption naming `name` otherwise.
  Status Validate(const std::string& name) const;
};

// The top levels for `shards` shards from the sample: at each node the split of the Splitting Overlap
// Algorithm (docs/design.md §3: axis and key order, fewest objects in the overlap set, then the thinner
// slab) among cuts that give the two subtrees sample shares within 0.05 of their shard shares. Fails when
// the sample cannot give every shard an object (fewer distinct keys than shards).
Result<TopLevels> ChooseTopLevels(const std::vector<ShardSample::Item>& sample, uint32_t shards);

}  // namespace mktree
