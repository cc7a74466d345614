// The self-clash's window of decoded leaves (docs/clash.md §3): the leaves the sweep plan has read and
// still needs, each with its objects' boxes and, for the objects some candidate pair may need
// (NeededObjects), their meshes and shapes; budgeted in bytes, apart from the page cache. A batch's
// reads go through the page cache on the calling thread, in plan order, so that the cache's counts do not
// depend on the threads; the meshes and shapes are decoded on all threads. Thread safety: one thread
// drives the window; the decoded leaves may be read by any number of threads between its calls.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "engine/clash/clash_focus.h"
#include "engine/clash/clash_reads.h"
#include "engine/clash/leaf_pairs.h"
#include "engine/clash/part_numbering.h"
#include "engine/clash/work_pool.h"
#include "engine/geometry/mesh_separation.h"
#include "mktree/clash.h"

namespace mktree::clash {

// One object of a decoded leaf: its float32 box (empty for a hidden object, ClashPart::hidden, so that it
// meets nothing), whether it is in the clash's focus and its partner set (true without), and its mesh and
// shape when some candidate pair may need them (NeededObjects).
struct LoadedObject {
  ObjectId id = 0;  // global
  Box3d box;
  bool in_focus = true;
  bool in_partner = true;  // in the focus's partner set (true without one)
  double resolution = 0;   // CoordinateResolution of its entry (with the shape: only candidates need it)
  std::unique_ptr<Mesh> mesh;
  std::unique_ptr<ClashShape> shape;
};
struct LoadedLeaf {
  std::vector<LoadedObject> objects;
  uint64_t bytes = 0;  // heap held by its meshes and shapes (about)
};

// What a leaf takes decoded, estimated before it is read from its encoded size (the entry headers with
// the vertex and triangle counts are in its pages): per object its box and the fixed part of a shape,
// per payload byte the double mesh and the parts its pairs build (hierarchy, classifier). Scenes whose
// leaves decode larger make the window exceed its budget by that error (docs/clash.md section 3).
constexpr uint64_t kDecodedBytesPerObject = 512;
constexpr uint64_t kDecodedBytesPerPayloadByte = 24;
inline uint64_t DecodedLeafEstimate(const LeafInfo& info) {
  return info.object_count * kDecodedBytesPerObject + kDecodedBytesPerPayloadByte * info.payload_bytes;
}

// The window's budget: ClashOptions::window_bytes, by default the larger of kDefaultClashWindowBytes and
// the decoded size of the parts' full page caches.
uint64_t WindowBudget(const ClashOptions& o, const PartNumbering& parts);

class ClashWindow {
 public:
  // Leaves numbered as `parts` numbers them; needed[k]: part k's objects that need a shape; `focus`: the
  // clash's focus (null: none). All must outlive the window.
  ClashWindow(const PartNumbering& parts, const std::vector<NeededObjects>& needed, const ClashFocus* focus);

  // Reads and decodes `leaves` (in this order) into the window: their pages on this thread, then the
  // needed objects' meshes and shapes on all threads. Adds the shapes to s->shapes_prepared and keeps
  // s->window_peak_bytes. The first error stops it (in leaf order, then object order).
  Status Read(const std::vector<uint32_t>& leaves, WorkPool& pool, ClashStats* s);
  // Counts again the leaves of `pairs` (their shapes build parts lazily in the narrow phase).
  void Recount(std::span<const LeafPair> pairs, ClashStats* s);
  // Drops the leaves from the window.
  void Drop(const std::vector<uint32_t>& leaves);

  const LoadedLeaf& leaf(uint32_t leaf) const { return *window_[leaf]; }
  const IoCount& io() const { return io_; }

 private:
  struct DecodeTask {
    size_t load;  // index into the read's leaves
    uint32_t pos;
  };

  const PartNumbering& parts_;
  const std::vector<NeededObjects>& needed_;
  const ClashFocus* focus_;
  std::vector<std::unique_ptr<LoadedLeaf>> window_;
  uint64_t bytes_ = 0;
  IoCount io_;
  // Scratch kept between reads.
  std::vector<PinnedLeaf> pinned_;
  std::vector<uint64_t> seen_;
  std::vector<DecodeTask> tasks_;
  std::vector<std::unique_ptr<LoadedLeaf>> loaded_;
  std::vector<Status> errors_;
};

}  // namespace mktree::clash
