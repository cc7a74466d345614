// Synthetic tanker: a deterministic, streamed generator of ship-like scenes of any size (docs/design.md §12).
//
// Layout
//   The hull envelope is the box TankerHullBounds(): x in [0, 300] m along the ship, y in [-25, 25] m across,
//   z in [0, 30] m up. Decks (z), longitudinal bulkheads (y) and transverse bulkheads (x) split it into a
//   grid of compartments. The number of compartments grows with N (about N / 60 up to ~1000 compartments,
//   then as 1000 * sqrt(N / 60000)), so a larger scene has both more and smaller compartments and more
//   objects in each: plates are tiled more finely and pipe racks and equipment clusters get denser.
//   Objects are emitted compartment by compartment (x-major, then y, then z), so nearby ids are nearby in
//   space, as in a real model exported deck by deck.
//
//   In each compartment, in this order:
//   - plates (30 %): deck plates tiling the compartment's floor, bulkhead panels tiling its aft (x) and
//     port (y) walls, and stiffeners (flat bars under the deck above, and vertical ones on the bulkhead);
//   - pipes (60 %): prisms of 8-16 sides, 0.05-0.5 m across, 0.3-40 m long, in racks of 3-12 parallel
//     pipes along x, y or z; long runs pass through bulkheads into the next compartments;
//   - equipment (10 %): clusters of 2-5 boxes, vertical cylinders (tanks) and horizontal cylinders (pumps,
//     motors) standing on the deck.
//   Class counts are exact: among the first m objects, round(0.3 m) are plates and round(0.1 m) equipment.
//   Every object lies inside the hull box. Vertices are rounded to 0.1 mm so that text output stays short.
//
// Meshes: every object is a closed, consistently outward-oriented triangle mesh (each edge is shared by
// exactly two triangles that traverse it in opposite directions; the signed volume is positive).
//
// Names: "<class>_<number>" with class pipe, plate or equipment and number the running count within the
// class, from 0, zero-padded to at least six digits: "pipe_000123", "plate_000045", "equipment_000007".
// (The id is already carried separately; a per-class count tells how many objects of the class came before.)
//
// Determinism: each object is derived from (seed, compartment, class, index in compartment) alone with a
// fixed PRNG (splitmix64) and IEEE arithmetic only (+ - * / sqrt; sines and cosines by a fixed series,
// not libm), so the same (objects, seed) gives the same bytes with every compiler and standard library.
// Memory is O(1) in N: the source keeps a few counters and the object being built.
#pragma once

#include <cstdint>
#include <memory>

#include "engine/scene/scene_source.h"
#include "mktree/geometry.h"

namespace mktree {

// The hull envelope in metres. Generated objects stay inside it.
Box3d TankerHullBounds();

// How many objects of each class a tanker of `objects` objects holds (exact, as generated).
struct TankerClassCounts {
  uint64_t pipes = 0;
  uint64_t plates = 0;
  uint64_t equipment = 0;
};
TankerClassCounts TankerExpectedCounts(uint64_t objects);

// A SceneSource that yields exactly `objects` objects with ids first_id, first_id + 1, ...
// REQUIRES: first_id + objects <= 2^32 (ids are 32-bit); otherwise Next() fails with InvalidArgument
// before producing anything.
std::unique_ptr<SceneSource> MakeTankerSource(uint64_t objects, uint64_t seed, ObjectId first_id = 0);
// Objects [begin, end) of the same scene (ids first_id + begin, ...), identical to theirs in the whole
// scene, generated without the ones before (a reader of a disjoint part: the MPI build, docs/shards.md).
std::unique_ptr<SceneSource> MakeTankerRangeSource(uint64_t objects, uint64_t seed, uint64_t begin,
                                                   uint64_t end, ObjectId first_id = 0);

}  // namespace mktree
