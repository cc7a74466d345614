// Fuzz target: opening a paged-file store (StoreReader::Open through Database::Open: header, sections,
// tree, object table, leaf filter, structural validation) and querying it (routing, leaf reads, entry
// decoding, exact geometry).
//
// Input: byte 0 picks the mode (mod 4); the rest is
//   0: the file, as is (header checks before any checksum: magic, version, parameters, sizes);
//   1: the file, every checksum its header lets us find recomputed (paged_store_image.h ResealPagedFile),
//      so that mutated header fields, sections and pages get past the checksums;
//   2, 3: structured: the parameter record and the contents of the pages and sections, separated, from
//      which a file with valid checksums is assembled (AssemblePagedFile): sections can change length
//      and still be found, which mutating a whole file hardly achieves.
// A store that opens is queried (a point and a box, the scene bounds and any queries of the last chunk,
// in AABB and exact mode). An answer must be sorted, without duplicates, and name existing objects.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "fuzz_util.h"
#include "paged_store_image.h"
#include "store_query_check.h"

namespace {

using mktree::fuzz::kChunkCount;
using mktree::fuzz::kSectionCount;
using mktree::fuzz::OpenAndQuery;

constexpr uint64_t kMaxMemPage = 64 * 1024;
constexpr size_t kMaxQueries = 8;

std::vector<mktree::Box3d> ParseQueries(std::span<const uint8_t> chunk) {
  std::vector<mktree::Box3d> out;
  for (size_t off = 0; off + 48 <= chunk.size() && out.size() < kMaxQueries; off += 48) {
    double v[6];
    std::memcpy(v, chunk.data() + off, 48);
    mktree::Box3d b;
    bool ok = true;
    for (int i = 0; i < 3; ++i) {
      ok = ok && std::isfinite(v[i]) && std::isfinite(v[i + 3]);
      b.min[i] = std::min(v[i], v[i + 3]);
      b.max[i] = std::max(v[i], v[i + 3]);
    }
    if (ok) out.push_back(b);
  }
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const int mode = data[0] % 4;
  ++data;
  --size;
  if (mode == 0 || mode == 1) {
    std::vector<uint8_t> file(data, data + size);
    if (mode == 1) mktree::fuzz::ResealPagedFile(&file, kMaxMemPage);
    OpenAndQuery(file, {});
    return 0;
  }
  if (size < mktree::kParamsRecordBytes) return 0;
  const std::span<const uint8_t> params(data, mktree::kParamsRecordBytes);
  mktree::BuildParams p;
  mktree::CodecOptions c;
  // Parameters that do not decode are assembled with the smallest page: Open must refuse them.
  const uint64_t mem_page = mktree::DecodeParams(params, &p, &c).ok() ? p.mem_page() : 512;
  if (mem_page < mktree::fuzz::kFixedHeaderBytes || mem_page > kMaxMemPage) return 0;
  auto chunks = mktree::fuzz::SplitChunks(data + params.size(), size - params.size());
  chunks.resize(std::max(chunks.size(), kChunkCount));
  if (chunks[0].size() > 256 * mem_page) return 0;
  std::span<const uint8_t> sections[kSectionCount];
  for (uint32_t i = 0; i < kSectionCount; ++i) sections[i] = chunks[1 + i];
  OpenAndQuery(mktree::fuzz::AssemblePagedFile(params, mem_page, chunks[0], sections),
               ParseQueries(chunks[9]));
  return 0;
}
