// The best-first walk that nearest and ray queries share (Hjaltason and Samet's incremental search): one
// priority queue over the trees of every part of a Database (a store, a revision's base and deltas, a
// sharded store's shards), keyed by a lower bound of how far along the query each item is, ties broken by
// rank (regions before objects) and then by global id:
//   kNode      an MKtree node, keyed by its box
//   kLeafBox   a leaf, keyed by its box: when it comes first, its leaf filter (the objects' quantised boxes,
//              in RAM) gives a tighter key and it goes back as a kLeaf
//   kLeaf      a leaf, keyed by the nearest of its objects' filter boxes: when it comes first, its pages
//              are read (the only reads), each live object's stored box keys it, and objects in order of
//              that key up to the Metric's bound get their exact key (geometry decoded only for them)
//   kObject    an object with its exact key: when it comes first, it is the next answer.
// So a leaf's pages are read only when its region is nearer than every answer still to come, and never
// when it is beyond the bound (the k-th exact key found so far, or the query's limit).
//
// The Metric (NearestMetric, RayMetric) says what "near" is:
//   double Key(size_t part, const Box3d& box) const          a lower bound of the key of anything inside
//                                                             box (store frame); +inf: nothing inside counts
//   double Rank(size_t part, const Box3d& box) const         cheaper, and increasing with Key (a squared
//   double KeyOfRank(double rank) const                       distance): Key(b) == KeyOfRank(Rank(b))
//   double Bound() const                                     keys above it cannot be answers
//   Result<bool> Exact(size_t part, const Mesh& m, uint8_t shape_flags, Found* f)
//                                                             the object's exact key, its point and normal
//                                                             (store frame) if within Bound()
//   void Found(double key)                                   an exact key was found (tightens Bound)
// Thread safety: a BestFirstSearch belongs to one thread; the parts' Databases may serve other queries.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <queue>
#include <utility>
#include <vector>

#include "engine/query/store_database.h"
#include "engine/tree/leaf_filter.h"

namespace mktree {

// One store among the parts a search covers.
struct SearchPart {
  const StoreDatabase* db = nullptr;
  const std::vector<ObjectId>* ids = nullptr;  // local -> global id, increasing; null: the same
  const std::vector<bool>* hidden = nullptr;   // by local id: not answered; null: none hidden
  ObjectId Global(ObjectId local) const { return ids ? (*ids)[local] : local; }
  bool Hidden(ObjectId local) const { return hidden && (*hidden)[local]; }
  const MKTree& tree() const { return db->reader().tree(); }
};

// An object's exact answer, in its part's store frame.
struct SearchFound {
  ObjectId id = 0;  // global
  double key = 0;   // distance, or t along a ray
  Vec3d point;
  Vec3d normal;
  uint32_t part = 0;
};

// Object i's mesh from the pinned leaf: the DecodedLeaf's cached copy, else decoded into *scratch (and
// cached there within its budget).
Result<const Mesh*> PinnedObjectMesh(const LeafSource& source, PinnedLeaf& pinned, size_t i, Mesh* scratch);

// A leaf's region key: the smallest key of its objects' filter boxes (the leaf's box without a filter),
// found by the metric's Rank (one KeyOfRank at the end).
template <typename Metric>
double LeafRegionKey(const MKTree& tree, uint32_t leaf, const Metric& metric, size_t part) {
  const LeafInfo& info = tree.leaves[leaf];
  if (tree.leaf_filter_begin.empty()) {
    Box3d b;
    for (int a = 0; a < 3; ++a) b.min[a] = info.box.min[a], b.max[a] = info.box.max[a];
    return metric.Key(part, b);
  }
  const uint8_t* q = tree.leaf_filter.data() + tree.leaf_filter_begin[leaf];
  double best = std::numeric_limits<double>::infinity();
  for (uint32_t i = 0; i < info.object_count; ++i)
    best = std::min(best, metric.Rank(part, DequantizeBox(info.box, q + i * kLeafFilterBytesPerObject)));
  return metric.KeyOfRank(best);
}

inline Box3d ToBox3d(const Box3f& f) {
  Box3d b;
  for (int a = 0; a < 3; ++a) b.min[a] = f.min[a], b.max[a] = f.max[a];
  return b;
}

template <typename Metric>
class BestFirstSearch {
 public:
  BestFirstSearch(std::vector<SearchPart> parts, Metric* metric) : parts_(std::move(parts)), metric_(metric) {
    for (size_t p = 0; p < parts_.size(); ++p) {
      const MKTree& t = parts_[p].tree();
      if (!t.empty()) Push(metric_->Key(p, ToBox3d(t.nodes[0].box)), kNode, 0, p, 0);
    }
  }

  // The next answer in order into *out and true; false when nothing is left within the bound.
  Result<bool> Next(SearchFound* out, QueryStats* s) {
    while (!queue_.empty()) {
      const Entry e = queue_.top();
      if (e.key > metric_->Bound()) {
        queue_ = {};
        return false;
      }
      queue_.pop();
      if (e.rank == kObject) {
        *out = found_[e.index];
        ++s->hits;
        return true;
      }
      MKTREE_RETURN_IF_ERROR(Expand(e, s));
    }
    return false;
  }

 private:
  enum Rank : uint8_t { kNode = 0, kLeafBox = 1, kLeaf = 2, kObject = 3 };
  struct Entry {
    double key;
    uint8_t rank;
    ObjectId id;
    uint32_t part;
    uint32_t index;
    bool operator>(const Entry& o) const {  // the queue's top is the smallest
      if (key != o.key) return key > o.key;
      if (rank != o.rank) return rank > o.rank;
      if (id != o.id) return id > o.id;
      if (part != o.part) return part > o.part;
      return index > o.index;
    }
  };

  void Push(double key, Rank rank, ObjectId id, size_t part, size_t index) {
    if (!(key <= metric_->Bound())) return;  // beyond the bound, or +inf / NaN: never an answer
    queue_.push({key, rank, id, static_cast<uint32_t>(part), static_cast<uint32_t>(index)});
  }

  Status Expand(const Entry& e, QueryStats* s) {
    const SearchPart& part = parts_[e.part];
    const MKTree& t = part.tree();
    auto key = [&](const Box3d& b) { return metric_->Key(e.part, b); };
    if (e.rank == kNode) {
      const TreeNode& n = t.nodes[e.index];
      if (n.is_leaf()) {
        Push(key(ToBox3d(t.leaves[n.leaf].box)), kLeafBox, 0, e.part, n.leaf);
        return Status::Ok();
      }
      ++s->internal_nodes_visited;
      for (uint32_t c : n.child) Push(key(ToBox3d(t.nodes[c].box)), kNode, 0, e.part, c);
      return Status::Ok();
    }
    if (e.rank == kLeafBox) {
      const double k = LeafRegionKey(t, e.index, *metric_, e.part);
      if (!(k <= metric_->Bound())) ++s->leaves_filtered;
      Push(k, kLeaf, 0, e.part, e.index);
      return Status::Ok();
    }
    return ReadLeaf(e.part, e.index, s);
  }

  // Reads the leaf and queues its objects' exact answers, objects in order of their box keys.
  Status ReadLeaf(size_t p, uint32_t leaf, QueryStats* s) {
    const SearchPart& part = parts_[p];
    struct Unpin {
      PinnedLeaf& leaf;
      ~Unpin() { leaf.Release(); }
    } unpin{pinned_};
    MKTREE_RETURN_IF_ERROR(part.db->leaves().ReadDecoded(leaf, s, &pinned_));
    ++s->leaves_visited;
    const DecodedLeaf& d = *pinned_.decoded;
    candidates_.clear();
    for (size_t i = 0; i < d.size(); ++i) {
      if (part.Hidden(d.ids()[i])) continue;
      ++s->candidates_tested;
      Box3d b;
      for (int a = 0; a < 3; ++a) b.min[a] = d.plane(a)[i], b.max[a] = d.plane(3 + a)[i];
      const double k = metric_->Key(p, b);
      if (k <= metric_->Bound()) candidates_.push_back({k, i});
    }
    std::sort(candidates_.begin(), candidates_.end());
    bool any = false;
    for (const auto& [k, i] : candidates_) {
      if (k > metric_->Bound()) break;
      MKTREE_ASSIGN_OR_RETURN(const Mesh* mesh, PinnedObjectMesh(part.db->leaves(), pinned_, i, &scratch_));
      SearchFound f;
      MKTREE_ASSIGN_OR_RETURN(const bool within, metric_->Exact(p, *mesh, d.shape_flags(i), &f));
      if (!within) continue;
      f.id = part.Global(d.ids()[i]);
      f.part = static_cast<uint32_t>(p);
      metric_->Found(f.key);
      found_.push_back(f);
      Push(f.key, kObject, f.id, p, found_.size() - 1);
      any = true;
    }
    s->leaves_with_hits += any;
    return Status::Ok();
  }

  std::vector<SearchPart> parts_;
  Metric* metric_;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue_;
  std::vector<SearchFound> found_;
  std::vector<std::pair<double, size_t>> candidates_;
  PinnedLeaf pinned_;
  Mesh scratch_;
};

}  // namespace mktree
