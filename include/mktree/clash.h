// Clash detection: which objects of a store meet or come too close, across the whole store
// (Database::SelfClash) or against one mesh (Database::Collide). docs/clash.md is the account.
//
// The separation s of two objects: s > 0 is the gap between them, s <= 0 they meet (surfaces cross or
// touch, or one solid lies wholly inside the other). With a clearance C >= 0 and a touch tolerance T >= 0
// a pair is
//   hard       it meets and its penetration depth exceeds T,
//   touch      it meets with depth <= T,
//   clearance  0 < s < C.
// The depth is known as an interval [depth_lower, depth_upper]: hard when depth_lower > T, touch when
// depth_upper <= T, otherwise hard with depth_exact false (a clash is never hidden as a touch).
// The store keeps vertices in float32, so an exact touch in the input may come back as a tiny gap or
// overlap: gaps and depths up to the pair's resolution (ClashPair::resolution) are touches too.
// Each unordered pair is reported once, with a < b. Points are in world coordinates.
//
//   mktree::ClashOptions o;
//   o.clearance = 0.05;
//   o.exclude_group_separator = "/";  // "pump3/flange" and "pump3/body" are not tested against each other
//   mktree::ClashStats stats;
//   Status st = db->SelfClash(o, [&](const mktree::ClashPair& p) { ... }, &stats);
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <numbers>
#include <string>

#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

enum class ClashClass : uint8_t { kHard, kTouch, kClearance };

enum class ClashMeeting : uint8_t {
  kCross,     // some triangle of a meets some triangle of b (crossing, touching or coplanar)
  kAInsideB,  // no triangles meet; a's solid (or a component of it) lies wholly inside b's
  kBInsideA,
  kApart,  // a clearance pair: s > 0
  // A touch by the store's resolution: the stored surfaces are apart by at most the rounding of their
  // float32 vertices (ClashPair::resolution), as exact touches in the input often end up.
  kResolutionGap,
};

// In Collide, b is the query mesh: b = kCollideObject, a is the store's object.
inline constexpr ObjectId kCollideObject = std::numeric_limits<ObjectId>::max();

struct ClashPair {
  ObjectId a = 0, b = 0;  // a < b
  ClashClass cls = ClashClass::kHard;
  ClashMeeting meeting = ClashMeeting::kCross;
  double distance = 0;  // s: the gap (clearance and resolution-gap pairs), -depth_upper (meeting pairs)
  double depth_lower = 0, depth_upper = 0;  // meeting pairs; 0 for clearance pairs
  bool depth_exact = true;                  // depth_lower == depth_upper
  // Clearance: the closest points of a and of b. Meeting: a point where they meet (the same point twice).
  Vec3d point_a, point_b;
  // How far the stored vertices of a and b together may be from the input's (float32 rounding in each
  // object's local frame): gaps and depths up to it are touches.
  double resolution = 0;
};

// Says whether the pair (a, b), a < b, is left out before its geometry is tested. Called from worker
// threads, possibly at once: it must be thread-safe, and a pure function of (a, b) for the answer to be
// deterministic.
using ClashExclude = std::function<bool(ObjectId a, ObjectId b)>;

// The self-clash's smallest default window of decoded leaves (docs/clash.md section 3 says why this size).
inline constexpr uint64_t kDefaultClashWindowBytes = uint64_t{32} << 20;

struct ClashOptions {
  double clearance = 0;            // C >= 0: pairs with 0 < s < C are clearance pairs
  double touch_tolerance = 0.002;  // T >= 0 (store units; 2 mm for metres)
  bool report_touch = true;        // false: touch pairs are counted, not reported
  // Non-empty: a pair whose names both contain this separator and agree up to its first occurrence is
  // excluded ("pump3/flange", "pump3/body" with "/"). A name without the separator is in no group.
  std::string exclude_group_separator;
  ClashExclude exclude;  // optional: the caller's own exclusion, after the group's
  // The most pairs given to the visitor; the rest are still found and counted (ClashStats::capped_pairs).
  uint64_t max_pairs = std::numeric_limits<uint64_t>::max();
  // Worker threads (0: one per core). The pairs and their order are the same for any count.
  unsigned threads = 1;
  // Self-clash: the memory for decoded leaves (meshes and narrow-phase shapes) kept between the leaf pairs
  // that need them, in bytes; 0: the larger of kDefaultClashWindowBytes and the decoded size of a full
  // page cache (OpenOptions::cache_pages pages at the estimate below), so the window grows with the cache
  // the caller gives. Planned from each leaf's estimated decoded size; a smaller window re-reads leaves
  // (through the page cache) and decodes them again, a larger one costs RAM up to what the sweep's front
  // holds. The answer is the same for any size.
  uint64_t window_bytes = 0;
  // Optional, on the calling thread: work done of total (leaf steps), for progress displays.
  std::function<void(uint64_t done, uint64_t total)> progress;
};

struct ClashStats {
  // I/O (the page cache's counts for this call) against the store's size.
  uint64_t pages_read = 0;      // cache misses = disk accesses
  uint64_t pages_touched = 0;   // page lookups in the cache
  uint64_t distinct_pages = 0;  // different pages looked up
  uint64_t store_pages = 0;     // leaf pages in the store
  uint64_t leaf_reads = 0;      // leaves read and decoded, re-reads included
  uint64_t leaf_rereads = 0;    // reads of a leaf that had left the window while it still had partners
  // The most memory the window of decoded leaves (meshes and narrow-phase shapes) held at once, about,
  // and the budget it was planned for (ClashOptions::window_bytes). The plan counts each leaf at its
  // estimated decoded size: the peak may exceed the budget by the estimate's error, or hold one leaf
  // pair that alone needs more (self-clash only).
  uint64_t window_peak_bytes = 0;
  uint64_t window_budget_bytes = 0;
  // Broad phase.
  uint64_t leaf_pairs_tree = 0;     // leaf pairs (a leaf with itself included) whose boxes grown by C meet
  uint64_t leaf_pairs_visited = 0;  // of those, the pairs the leaf filter let through: read and tested
  uint64_t candidate_pairs = 0;     // object pairs whose float32 boxes grown by C meet
  uint64_t excluded_pairs = 0;      // candidates left out by an exclusion (not tested)
  // Narrow phase (engine/geometry/mesh_separation.h).
  uint64_t bound_rejects = 0;
  uint64_t triangle_tests = 0;
  uint64_t containment_tests = 0;
  // Narrow-phase shapes: objects prepared (26-DOP and vertex extent), and of those the triangle
  // hierarchies and point-in-solid classifiers built on first use by a pair that needed them.
  uint64_t shapes_prepared = 0;
  uint64_t hierarchies_built = 0;
  uint64_t classifiers_built = 0;
  // Pairs found, by class (capped and unreported touch pairs included), and what was not reported.
  uint64_t hard = 0, touch = 0, clearance = 0;
  uint64_t reported_pairs = 0;
  uint64_t capped_pairs = 0;        // found but beyond max_pairs
  uint64_t unreported_touches = 0;  // touch pairs with report_touch false
  // Wall seconds by phase.
  double broad_seconds = 0, read_seconds = 0, narrow_seconds = 0, total_seconds = 0;
};

// Receives the pairs, on the calling thread, in a deterministic order.
using ClashVisitor = std::function<void(const ClashPair&)>;

// A rigid motion x -> rotation * x + translation (world coordinates); rotation row-major, a proper
// rotation (orthonormal, determinant +1, checked to 1e-9).
struct RigidTransform {
  double rotation[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  Vec3d translation;

  // Rotation about x by ax, then about y by ay, then about z by az (degrees): R = Rz Ry Rx.
  static RigidTransform FromEulerDegrees(double ax, double ay, double az, const Vec3d& t = {}) {
    const double k = std::numbers::pi / 180;
    const double cx = std::cos(ax * k), sx = std::sin(ax * k), cy = std::cos(ay * k), sy = std::sin(ay * k),
                 cz = std::cos(az * k), sz = std::sin(az * k);
    RigidTransform r;
    const double m[9] = {cz * cy,
                         cz * sy * sx - sz * cx,
                         cz * sy * cx + sz * sx,
                         sz * cy,
                         sz * sy * sx + cz * cx,
                         sz * sy * cx - cz * sx,
                         -sy,
                         cy * sx,
                         cy * cx};
    for (int i = 0; i < 9; ++i) r.rotation[i] = m[i];
    r.translation = t;
    return r;
  }
  Vec3d Apply(const Vec3d& p) const {
    const double* m = rotation;
    return {m[0] * p.x + m[1] * p.y + m[2] * p.z + translation.x,
            m[3] * p.x + m[4] * p.y + m[5] * p.z + translation.y,
            m[6] * p.x + m[7] * p.y + m[8] * p.z + translation.z};
  }
};

}  // namespace mktree
