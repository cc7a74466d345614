#include "engine/tree/build_layout.h"

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <utility>

#include "engine/tree/build_threads.h"

#ifdef __linux__
#include <sys/mman.h>
#endif

namespace mktree::build {
namespace {

// Float -> uint32 whose unsigned order is the float order (for the radix sort).
inline uint32_t SortableBits(float f) {
  const uint32_t u = std::bit_cast<uint32_t>(f);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

// LSD radix sort of (key << 32 | payload) pairs by the key, stable, writing the payloads in that order to
// *out (resized; b is scratch): 3 passes of 11/11/10 bits, far faster than an indirect comparison sort at
// 10M. `count` holds the three digits' counts (kRadixBuckets each), counted as *a was written; the last pass
// writes the payloads directly.
constexpr size_t kRadixBuckets = size_t{1} << 11;
void RadixSortPayloads(BuildVector<uint64_t>* a, BuildVector<uint64_t>* b, uint32_t* count,
                       BuildVector<uint32_t>* out) {
  const size_t n = a->size();
  b->resize(n);
  out->resize(n);
  constexpr int kShift[3] = {32, 43, 54};
  for (int pass = 0; pass < 3; ++pass) {
    uint32_t* c = count + pass * kRadixBuckets;
    uint32_t sum = 0;  // (fewer than 2^32 objects: BuildMKTree's REQUIRES)
    for (size_t i = 0; i < kRadixBuckets; ++i) {
      const uint32_t here = c[i];
      c[i] = sum;
      sum += here;
    }
    const int shift = kShift[pass];
    if (pass < 2) {
      for (uint64_t v : *a) (*b)[c[(v >> shift) & 0x7ff]++] = v;
      a->swap(*b);
    } else {
      for (uint64_t v : *a) (*out)[c[(v >> shift) & 0x7ff]++] = static_cast<uint32_t>(v);
    }
  }
}

// Object indices sorted by one key (axis, min or max), stable (see SortKeyOrders). The radix digits are
// counted as the keys are written.
void SortByKey(const BuildVector<Box3f>& box, int axis, bool use_max, BuildVector<uint64_t>* a,
               BuildVector<uint64_t>* b, BuildVector<uint32_t>* out) {
  const size_t n = box.size();
  a->resize(n);
  // The top digit (sign, exponent) takes few values: neighbours' counts go to four copies (the last
  // three after the three digits' blocks), or each increment would wait for the last one.
  constexpr size_t kTop = kRadixBuckets / 2;
  std::vector<uint32_t> count(3 * kRadixBuckets + 3 * kTop, 0);
  uint32_t* const low = count.data();
  uint32_t* const mid = low + kRadixBuckets;
  uint32_t* const top = mid + kRadixBuckets;
  auto top_copy = [&](size_t copy) { return copy == 0 ? top : top + kRadixBuckets + (copy - 1) * kTop; };
  uint64_t* const keys = a->data();
  auto add = [&](size_t i, size_t copy) {
    const float k = use_max ? box[i].max[axis] : box[i].min[axis];
    const uint32_t bits = SortableBits(k);
    keys[i] = (uint64_t{bits} << 32) | i;
    ++low[bits & 0x7ff];
    ++mid[(bits >> 11) & 0x7ff];
    ++top_copy(copy)[bits >> 22];
  };
  size_t i = 0;
  for (; i + 4 <= n; i += 4) add(i, 0), add(i + 1, 1), add(i + 2, 2), add(i + 3, 3);
  for (; i < n; ++i) add(i, 0);
  for (size_t copy = 1; copy < 4; ++copy)
    for (size_t d = 0; d < kTop; ++d) top[d] += top_copy(copy)[d];
  RadixSortPayloads(a, b, count.data(), out);
}

// Spreads the low 10 bits of v to every third bit (Morton code helper).
inline uint32_t Spread3(uint32_t v) {
  v &= 0x3ff;
  v = (v | (v << 16)) & 0x030000ff;
  v = (v | (v << 8)) & 0x0300f00f;
  v = (v | (v << 4)) & 0x030c30c3;
  v = (v | (v << 2)) & 0x09249249;
  return v;
}

// Records copied between two releases of the pages read (ReleaseReadPages).
constexpr size_t kReleaseObjects = size_t{1} << 15;

// Gives back the whole pages of bytes [from, to) of the storage at `base`, but never the page `base` is in
// (the allocator's header of the block may share it): those records are not read again, and freeing
// their vector later reads only its header.
void ReleaseReadPages(const char* base, size_t from, size_t to) {
#ifdef __linux__
  constexpr uintptr_t kPage = 4096;
  const uintptr_t b = reinterpret_cast<uintptr_t>(base);
  const uintptr_t first = std::max((b + from + kPage - 1) & ~(kPage - 1), (b & ~(kPage - 1)) + kPage);
  const uintptr_t last = (b + to) & ~(kPage - 1);
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_DONTNEED);
#else
  (void)base, (void)from, (void)to;
#endif
}

}  // namespace

BuildRecords SpatialLayout(std::vector<BuildObject> records, const Box3f& all, BuildVector<ObjectId>* ids,
                           int threads) {
  const size_t n = records.size();
  constexpr uint32_t kCellsPerAxis = 16;
  constexpr size_t kCells = kCellsPerAxis * kCellsPerAxis * kCellsPerAxis;
  BuildVector<uint16_t> cell(n);
  // A counting sort by cell on the two halves: each counts its own objects, and a cell's objects from the
  // first half go before those from the second (input order within a cell).
  std::vector<size_t> count(2 * kCells, 0);
  double scale[3];  // cells per metre (a multiply per axis, not a division: the cells only group)
  for (int w = 0; w < 3; ++w) {
    const double ext = double{all.max[w]} - all.min[w];
    scale[w] = ext > 0 ? kCellsPerAxis / ext : 0;
  }
  RunOnHalves(n, threads, [&](size_t lo, size_t hi) {
    size_t* const counts = count.data() + (lo == 0 ? 0 : kCells);
    for (size_t i = lo; i < hi; ++i) {
      const Box3f& bx = records[i].box;
      uint32_t code = 0;
      for (int w = 0; w < 3; ++w) {
        const double c = 0.5 * (double{bx.min[w]} + bx.max[w]) - all.min[w];
        constexpr double kTop = kCellsPerAxis - 1;
        code |= Spread3(static_cast<uint32_t>(std::clamp(c * scale[w], 0.0, kTop))) << w;
      }
      cell[i] = static_cast<uint16_t>(code);
      ++counts[code];
    }
  });
  size_t start = 0;  // count[half * kCells + c] becomes where that half's objects of cell c go
  for (size_t c = 0; c < kCells; ++c) {
    for (size_t half : {size_t{0}, kCells}) {
      const size_t here = count[half + c];
      count[half + c] = start;
      start += here;
    }
  }
  BuildRecords rec;
  rec.box.resize(n);
  rec.bytes.resize(n);
  ids->resize(n);
  // Scattered in input order, so that the records read are given back as the copy goes (a gather in
  // layout order reads them at random: the records and their copy would be resident together). The
  // writes go to one run per cell, each filled in order.
  const char* const base = reinterpret_cast<const char*>(records.data());
  RunOnHalves(n, threads, [&](size_t lo, size_t hi) {
    size_t* const next = count.data() + (lo == 0 ? 0 : kCells);
    size_t given_back = lo;
    for (size_t i = lo; i < hi; ++i) {
      const size_t to = next[cell[i]]++;
      rec.box[to] = records[i].box;
      rec.bytes[to] = records[i].encoded_bytes;
      (*ids)[to] = records[i].id;
      if (i + 1 - given_back >= kReleaseObjects || i + 1 == hi) {
        ReleaseReadPages(base, given_back * sizeof(BuildObject), (i + 1) * sizeof(BuildObject));
        given_back = i + 1;
      }
    }
  });
  return rec;
}

void SortKeyOrders(const BuildVector<Box3f>& box, std::array<BuildVector<uint32_t>, 6>* lists,
                   const std::function<void(int)>& sorted) {
  BuildVector<uint64_t> a, b;
  for (int l = 0; l < 6; ++l) {
    SortByKey(box, l / 2, l % 2 == 1, &a, &b, &(*lists)[l]);
    sorted(l);
  }
}

}  // namespace mktree::build
