// The workload of changes_bench: a synthetic tanker and a fixed, seeded script of change batches on it,
// the same for every engine (mktree and its peers), so that each engine starts from the same objects and
// ends with the same live set.
//
// A batch of k changes holds about k/3 each of:
//   add      a copy of a random object of the tanker, moved by a random offset that keeps its box inside
//            the scene's box; it gets the next new id (ids are never reused: N, N+1, ... in batch order,
//            as mktree::ChangeWriter gives them);
//   remove   a random live id;
//   replace  a random live id gets a moved copy of a random tanker object as its geometry.
// No id is removed or replaced twice in one batch. A batch of 1 takes the three kinds in turn.
//
// The boxes of moved copies are exact: a mesh moved by adding the offset to each vertex has the bounds of
// the original plus the offset (rounding is monotone), rounded outward to float32 as SceneObject::Aabb.
//
// Thread safety: none needed; values only.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "mktree/build.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree::bench {

enum class ChangeKind : uint8_t { kAdd, kRemove, kReplace };

struct Change {
  ChangeKind kind = ChangeKind::kAdd;
  ObjectId id = 0;      // add: the id the store gives the copy; remove, replace: the live object
  ObjectId source = 0;  // add, replace: the tanker object copied
  Vec3d offset;         // add, replace: how far the copy is moved
  Box3f box;            // add, replace: the copy's box
  Box3f old_box;        // remove, replace: the object's box before the change
};

struct ChangeBatchScript {
  std::vector<Change> changes;
};

// The batches of one size, applied one after another.
struct BatchGroup {
  uint64_t size = 0;
  std::vector<ChangeBatchScript> batches;
};

// Where an object's geometry comes from: tanker object `source` moved by `offset` (an unchanged tanker
// object is its own source with a zero offset).
struct GeometryOrigin {
  ObjectId source = 0;
  Vec3d offset;
  bool moved = false;
};

struct ChangeWorkload {
  uint64_t objects = 0;  // N, the tanker's objects (ids 0..N-1)
  uint64_t seed = 1;     // the tanker's seed ("tanker:N:SEED")
  uint64_t change_seed = 1;
  Box3d scene_bounds;              // of the tanker's objects
  std::vector<Box3f> base_boxes;   // the tanker's boxes, by id
  std::vector<BatchGroup> groups;  // in the order they are applied
  // After every batch of every group: by id (0 .. next id - 1), whether it is live, its box and its
  // geometry's origin.
  std::vector<uint8_t> live;
  std::vector<Box3f> boxes;
  std::vector<GeometryOrigin> origins;

  uint64_t live_count() const;
  // The build input naming the tanker: "tanker:N:SEED".
  std::string TankerInput() const { return "tanker:" + std::to_string(objects) + ":" + std::to_string(seed); }
};

// Generates the tanker once (its boxes) and the script: `batches[i]` batches of `sizes[i]` changes.
Result<ChangeWorkload> MakeChangeWorkload(uint64_t objects, uint64_t seed, uint64_t change_seed,
                                          const std::vector<uint64_t>& sizes,
                                          const std::vector<uint64_t>& batches);

// The tanker objects that the script copies (every add's and replace's source), read in one pass over the
// generator: meshes, names and all.
using SourceObjects = std::unordered_map<ObjectId, SceneObject>;
Result<SourceObjects> LoadSourceObjects(const ChangeWorkload& workload);

// `source` moved by `offset`, named "<name>+moved", with id `id`.
SceneObject MovedCopy(const SceneObject& source, const Vec3d& offset, ObjectId id);

// The live set after the whole script, in id order, as a build's ObjectSource (what a full rebuild of the
// changed store has to read). `workload` and `sources` must outlive the returned function.
ObjectSource LiveSetSource(const ChangeWorkload& workload, const SourceObjects& sources);

// The store every mktree build of changes_bench uses: paged file, 12 KiB pages (4096 x 3), zstd.
BuildOptions ChangesBenchBuildOptions();

}  // namespace mktree::bench
