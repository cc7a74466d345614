// The leaf filter: a conservative summary, kept in RAM, of where each leaf's objects are, so that a
// query skips a leaf the tree routes it to when none of that leaf's objects' boxes can meet the query.
//
// Why: the MKtree partitions objects, not space, so a leaf's box R is the union of its objects' boxes and
// holds much free space (a long pipe stretches R across a compartment): without the filter a random point
// reaches several leaves for each one that holds an answer (bench/README.md; see also
// BuildTuning::split_min_gain). The SplitTrees only speak for overlap slabs; this speaks for the leaves.
//
// Each object's float32 box is quantized to 10 bits per bound inside its leaf's box (8 bytes per object),
// rounded outward, so the quantized box contains the real one: the filter can only let through a leaf
// that has nothing (a false positive costs one read), never drop one that has something. 10 bits let
// through about a quarter of the empty leaves 8 bits do, and 12 would need a ninth byte (bench/README.md).
#pragma once

#include <cstdint>

#include "mktree/geometry.h"

namespace mktree {

inline constexpr uint32_t kLeafFilterBytesPerObject = 8;
inline constexpr int kLeafFilterLevels = 1023;  // the top level: levels 0..1023, 10 bits

// Quantizes `object` (inside `leaf`) into out[0..7]: a little-endian uint64 whose bits 10 k .. 10 k + 9
// hold level k of min x, y, z, max x, y, z (k = 0..5), each in 0..1023; bits 60-63 are zero.
void QuantizeBox(const Box3f& leaf, const Box3f& object, uint8_t* out);
// The box a quantized entry stands for (contains the original object box).
Box3d DequantizeBox(const Box3f& leaf, const uint8_t* q);
// Does any of the `count` quantized boxes at q contain p / meet box?
bool FilterMeetsPoint(const Box3f& leaf, const uint8_t* q, uint32_t count, const Vec3d& p);
bool FilterMeetsBox(const Box3f& leaf, const uint8_t* q, uint32_t count, const Box3d& box);

}  // namespace mktree
