#include "engine/shard/top_levels.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

namespace mktree {

namespace {

// How far a side's sample share may be from its shards' share.
constexpr double kShareTolerance = 0.05;

// splitmix64 of the id with a fixed seed: the sample is the same on every run.
uint64_t SampleHash(ObjectId id) {
  uint64_t z = uint64_t{id} + 0x9e3779b97f4a7c15ull * 0x5eed;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

bool HashLess(const ShardSample::Item& a, const ShardSample::Item& b) {
  return a.hash != b.hash ? a.hash < b.hash : a.id < b.id;
}

double Key(const Box3d& b, int axis, ShardKey key) {
  return key == ShardKey::kMin ? b.min[axis] : b.max[axis];
}

struct Chooser {
  const std::vector<ShardSample::Item>& items;
  std::vector<TopNode>* nodes;
  uint32_t next_shard = 0;

  struct Best {
    bool found = false;
    uint64_t overlap = 0;
    double slab = 0;
    uint64_t off_target = 0;
    int axis = 0;
    ShardKey key = ShardKey::kMin;
    double cut = 0;
  };

  // The best split of `idx` into k1 = shards / 2 shards' share and the rest's. Its own function, so that
  // its sorted copies (36 bytes an item) are freed before Split recurses.
  Best FindSplit(const std::vector<uint32_t>& idx, uint32_t shards) const {
    const uint32_t k1 = shards / 2, k2 = shards - k1;
    const uint64_t n = idx.size();
    const double share = static_cast<double>(k1) / shards;
    const uint64_t target = static_cast<uint64_t>(std::llround(share * static_cast<double>(n)));
    const double lo_f = std::ceil((share - kShareTolerance) * static_cast<double>(n));
    const uint64_t lo = std::max<uint64_t>({k1, lo_f > 0 ? static_cast<uint64_t>(lo_f) : 0, 1});
    const uint64_t hi_w =
        static_cast<uint64_t>(std::floor((share + kShareTolerance) * static_cast<double>(n)));
    const uint64_t hi = std::min<uint64_t>(n >= k2 ? n - k2 : 0, hi_w);
    Best best;
    std::vector<uint32_t> order(idx);
    std::vector<double> mins(n), maxs(n), pre_max(n), suf_min(n + 1);
    for (int axis = 0; axis < 3; ++axis) {
      for (uint64_t i = 0; i < n; ++i) {
        mins[i] = items[idx[i]].box.min[axis];
        maxs[i] = items[idx[i]].box.max[axis];
      }
      std::sort(mins.begin(), mins.end());
      std::sort(maxs.begin(), maxs.end());
      for (ShardKey key : {ShardKey::kMin, ShardKey::kMax}) {
        std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
          const double ka = Key(items[a].box, axis, key), kb = Key(items[b].box, axis, key);
          return ka != kb ? ka < kb : items[a].id < items[b].id;
        });
        for (uint64_t i = 0; i < n; ++i)
          pre_max[i] = std::max(i ? pre_max[i - 1] : -INFINITY, items[order[i]].box.max[axis]);
        suf_min[n] = INFINITY;
        for (uint64_t i = n; i-- > 0;) suf_min[i] = std::min(suf_min[i + 1], items[order[i]].box.min[axis]);
        for (uint64_t k = lo; k <= hi && k < n; ++k) {
          const double cut = Key(items[order[k]].box, axis, key);
          if (!(Key(items[order[k - 1]].box, axis, key) < cut)) continue;  // the rule must split here
          const double a = suf_min[k], b = pre_max[k - 1];
          uint64_t overlap = 0;
          if (a < b) {  // Sm: max > a and min < b
            const uint64_t max_le_a = std::upper_bound(maxs.begin(), maxs.end(), a) - maxs.begin();
            const uint64_t min_ge_b = mins.end() - std::lower_bound(mins.begin(), mins.end(), b);
            overlap = n - max_le_a - min_ge_b;
          }
          const uint64_t off = k > target ? k - target : target - k;
          const bool better = !best.found || overlap < best.overlap ||
                              (overlap == best.overlap &&
                               (b - a < best.slab || (b - a == best.slab && off < best.off_target)));
          if (better) best = {true, overlap, b - a, off, axis, key, cut};
        }
      }
    }
    return best;
  }

  Status Split(std::vector<uint32_t> idx, uint32_t shards) {
    const uint32_t at = static_cast<uint32_t>(nodes->size());
    nodes->emplace_back();
    if (shards == 1) {
      (*nodes)[at].shard = next_shard++;
      return Status::Ok();
    }
    const uint32_t k1 = shards / 2, k2 = shards - k1;
    const uint64_t n = idx.size();
    const Best best = FindSplit(idx, shards);
    if (!best.found)
      return Status::InvalidArgument("cannot make " + std::to_string(shards) + " shards of " +
                                     std::to_string(n) +
                                     " sampled objects: too few objects with distinct boxes");
    TopNode& node = (*nodes)[at];
    node.axis = static_cast<uint8_t>(best.axis);
    node.key = best.key;
    node.cut = best.cut;
    std::vector<uint32_t> left, right;
    for (uint32_t i : idx) (Key(items[i].box, best.axis, best.key) < best.cut ? left : right).push_back(i);
    idx.clear();
    idx.shrink_to_fit();
    (*nodes)[at].child[0] = static_cast<uint32_t>(nodes->size());
    MKTREE_RETURN_IF_ERROR(Split(std::move(left), k1));
    (*nodes)[at].child[1] = static_cast<uint32_t>(nodes->size());
    return Split(std::move(right), k2);
  }
};

}  // namespace

void ShardSample::Add(ObjectId id, const Box3d& box) {
  Item item{SampleHash(id), id, box};
  if (heap_.size() < capacity_) {
    heap_.push_back(item);
    std::push_heap(heap_.begin(), heap_.end(), HashLess);
  } else if (capacity_ > 0 && HashLess(item, heap_.front())) {
    std::pop_heap(heap_.begin(), heap_.end(), HashLess);
    heap_.back() = item;
    std::push_heap(heap_.begin(), heap_.end(), HashLess);
  }
}

void ShardSample::Merge(const ShardSample& other) {
  for (const Item& i : other.heap_) {
    if (heap_.size() < capacity_) {
      heap_.push_back(i);
      std::push_heap(heap_.begin(), heap_.end(), HashLess);
    } else if (capacity_ > 0 && HashLess(i, heap_.front())) {
      std::pop_heap(heap_.begin(), heap_.end(), HashLess);
      heap_.back() = i;
      std::push_heap(heap_.begin(), heap_.end(), HashLess);
    }
  }
}

std::vector<ShardSample::Item> ShardSample::Items() const& { return ShardSample(*this).Items(); }

std::vector<ShardSample::Item> ShardSample::Items() && {
  std::vector<Item> out = std::move(heap_);
  heap_ = {};
  std::sort(out.begin(), out.end(), [](const Item& a, const Item& b) { return a.id < b.id; });
  return out;
}

uint32_t TopLevels::ShardOf(const Box3d& box) const {
  uint32_t n = 0;
  while (!nodes[n].is_leaf()) {
    const TopNode& t = nodes[n];
    n = t.child[Key(box, t.axis, t.key) < t.cut ? 0 : 1];
  }
  return nodes[n].shard;
}

bool TopLevels::CanRouteTo(const Box3d& box, double slack, uint32_t shard) const {
  uint32_t stack[128];
  size_t depth = 0;
  stack[depth++] = 0;
  while (depth > 0) {
    const TopNode& t = nodes[stack[--depth]];
    if (t.is_leaf()) {
      if (t.shard == shard) return true;
      continue;
    }
    const double k = Key(box, t.axis, t.key);
    if (depth + 2 > sizeof stack / sizeof stack[0]) return true;  // deeper than Validate allows: say maybe
    if (k - slack < t.cut) stack[depth++] = t.child[0];
    if (!(k + slack < t.cut)) stack[depth++] = t.child[1];
  }
  return false;
}

Status TopLevels::Validate(const std::string& name) const {
  auto bad = [&](const std::string& what) { return Status::Corruption(name + ": top levels: " + what); };
  if (shard_count == 0 || nodes.size() != 2 * uint64_t{shard_count} - 1) return bad("wrong node count");
  // Preorder: walking from the root, each node is the next index; shards are the leaves left to right.
  uint32_t next = 0, shard = 0;
  std::vector<std::pair<uint32_t, uint32_t>> stack{{0, 0}};  // node, depth
  while (!stack.empty()) {
    const auto [n, depth] = stack.back();
    stack.pop_back();
    if (n != next || depth > 64) return bad("not a tree in preorder");
    ++next;
    const TopNode& t = nodes[n];
    if (t.is_leaf()) {
      if (t.shard != shard++ || t.child[0] != kNoShard || t.child[1] != kNoShard) return bad("bad leaf");
      continue;
    }
    if (t.axis > 2 || static_cast<uint8_t>(t.key) > 1 || !std::isfinite(t.cut) ||
        t.child[0] >= nodes.size() || t.child[1] >= nodes.size())
      return bad("bad internal node " + std::to_string(n));
    stack.push_back({t.child[1], depth + 1});
    stack.push_back({t.child[0], depth + 1});
  }
  if (next != nodes.size() || shard != shard_count) return bad("nodes or shards left over");
  return Status::Ok();
}

Result<TopLevels> ChooseTopLevels(const std::vector<ShardSample::Item>& sample, uint32_t shards) {
  if (shards == 0) return Status::InvalidArgument("shards must be at least 1");
  TopLevels top;
  top.shard_count = shards;
  Chooser chooser{sample, &top.nodes};
  std::vector<uint32_t> all(sample.size());
  std::iota(all.begin(), all.end(), 0u);
  if (sample.size() < shards)
    return Status::InvalidArgument("cannot make " + std::to_string(shards) + " shards of " +
                                   std::to_string(sample.size()) + " objects");
  MKTREE_RETURN_IF_ERROR(chooser.Split(std::move(all), shards));
  return top;
}

}  // namespace mktree
