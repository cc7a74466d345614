// Fuzz target: leaf decoding (engine/store_format/leaf_codec.h, engine/store_format/leaf_reader.h,
// engine/store_format/object_codec.h).
//
// Input: byte 0 picks the mode (mod 4), byte 1 the page size (512 << (byte % 4)), the rest is the data.
//   0: a run of object entries (ParseObjectEntry, then DecodeObjectMesh of each);
//   1: leaf pages, each page's checksum recomputed over the fuzzer's bytes (so header fields, magic and
//      version stay as mutated, and the checksum is not what stops the parse);
//   2: leaf pages exactly as given (the checksum check itself);
//   3: leaf pages resealed with SealPage (valid magic and version, the other header fields as given).
// Pages are read through a PageCache over a MemoryPageStore with ReadLeaf, as queries read them, and
// every entry of a leaf that parses is decoded. A decoded mesh must match its entry's counts and index
// only its own vertices.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <vector>

#include "engine/store_format/leaf_reader.h"
#include "engine/store_format/object_codec.h"
#include "fuzz_util.h"
#include "storage/byte_io.h"
#include "storage/memory_page_store.h"
#include "storage/page_cache.h"
#include "storage/page_codec.h"

namespace {

using mktree::Status;
using mktree::storage_internal::Get;
using mktree::storage_internal::Put;

constexpr size_t kMaxPages = 64;

void Decode(const mktree::ObjectEntryView& e) {
  mktree::Mesh mesh;
  if (Status st = mktree::DecodeObjectMesh(e, &mesh); !st.ok()) {
    mktree::fuzz::Refused(st.ToString());
    return;
  }
  if (mesh.vertex_count() != e.vertex_count || mesh.triangle_count() != e.triangle_count) std::abort();
  for (uint32_t t : mesh.triangles)
    if (t >= mesh.vertex_count()) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const int mode = data[0] % 4;
  const uint64_t mem_page = uint64_t{512} << (data[1] % 4);
  data += 2;
  size -= 2;

  if (mode == 0) {
    size_t off = 0;
    bool all = true;
    while (off < size) {
      mktree::ObjectEntryView e;
      if (Status st = mktree::ParseObjectEntry(data + off, size - off, &e); !st.ok()) {
        mktree::fuzz::Refused(st.ToString());
        all = false;
        break;
      }
      if (e.entry_bytes() < mktree::kObjectEntryHeaderBytes || e.entry_bytes() > size - off) std::abort();
      Decode(e);
      off += e.entry_bytes();
    }
    if (all) ++mktree::fuzz::g_accepted;
    return 0;
  }

  const size_t page_count = std::min(kMaxPages, std::max<size_t>(1, (size + mem_page - 1) / mem_page));
  mktree::MemoryPageStore store(mem_page, "fuzz-leaf");
  std::vector<uint8_t> page(mem_page);
  for (size_t p = 0; p < page_count; ++p) {
    std::fill(page.begin(), page.end(), 0);
    const size_t from = p * mem_page;
    if (from < size) std::memcpy(page.data(), data + from, std::min<size_t>(mem_page, size - from));
    if (mode == 1) {
      Put<uint64_t>(page.data() + 24, mktree::PageChecksum(page.data(), mem_page));
    } else if (mode == 3) {
      mktree::PageHeader h;
      h.leaf_index = Get<uint32_t>(page.data() + 8);
      h.page_in_leaf = Get<uint32_t>(page.data() + 12);
      h.page_count = Get<uint32_t>(page.data() + 16);
      h.payload_bytes = Get<uint32_t>(page.data() + 20);
      mktree::SealPage(h, page.data(), mem_page);
    }
    if (!store.WritePage(p, page.data()).ok()) std::abort();
  }

  mktree::LeafInfo info;
  info.first_page = 0;
  info.page_count = static_cast<uint32_t>(page_count);
  const uint32_t leaf = Get<uint32_t>(store.mutable_page(0) + 8);  // the leaf its first page names
  // The tree's side of the check: the count the leaf header claims, a box holding anything, and an object
  // table of kObjects objects.
  constexpr size_t kObjects = 1024;
  info.object_count = Get<uint32_t>(store.mutable_page(0) + mktree::kPageHeaderBytes);
  for (int k = 0; k < 3; ++k) {
    info.box.min[k] = -std::numeric_limits<float>::infinity();
    info.box.max[k] = std::numeric_limits<float>::infinity();
  }
  // The object table's digest for this leaf is taken from the ids its entries hold (below kObjects), so
  // that a well-formed leaf reaches the decoders.
  mktree::ObjectTable objects;
  objects.count = kObjects;
  constexpr uint32_t kLeaves = 1 << 16;  // a leaf index past them has no digest (refused)
  objects.leaf_digest.assign(kLeaves, 0);
  if (leaf < kLeaves) {
    std::vector<const uint8_t*> data;
    for (uint64_t p = 0; p < page_count; ++p) data.push_back(store.mutable_page(p));
    mktree::LeafView view;
    if (mktree::LeafView::Parse(store.name(), leaf, 0, data, mem_page, true, &view).ok())
      for (const mktree::ObjectEntryView& e : view.entries())
        if (e.id < kObjects) objects.leaf_digest[leaf] += mktree::ObjectIdHash(e.id);
  }
  mktree::PageCache cache(&store, 2);
  mktree::QueryStats stats;
  mktree::PinnedLeaf pinned;
  if (Status st = mktree::ReadLeaf(cache, store.name(), leaf, info, objects, mem_page, true, &stats, &pinned);
      !st.ok()) {
    mktree::fuzz::Refused(st.ToString());
    return 0;
  }
  for (const mktree::ObjectEntryView& e : pinned.view.entries()) Decode(e);
  ++mktree::fuzz::g_accepted;
  return 0;
}
