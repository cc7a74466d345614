// The one door to a store's leaves: the store's reader, the page cache its pages go through, and the
// checks every read makes (a page's checksum on its first read after loading, the entries against the
// tree and the object table). Query, clash, render and export read leaves only through a LeafSource, by
// leaf number; the living store will put its changes behind the same door.
// Thread safety: every method is const and may be called from many threads at once (the page cache is
// thread-safe); a PinnedLeaf belongs to the thread that reads into it.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "engine/store_format/leaf_reader.h"
#include "engine/store_format/object_codec.h"
#include "engine/store_format/store_file.h"
#include "mktree/query_stats.h"
#include "mktree/status.h"
#include "storage/page_cache.h"

namespace mktree {

class LeafSource {
 public:
  // The most leaves VisitCachedDecoded passes at once.
  static constexpr size_t kMaxVisited = PageCache::kMaxVisitedRuns;

  // REQUIRES: `cache` is over reader.pages(); both outlive the source (a copy reads the same leaves).
  LeafSource(const StoreReader& reader, PageCache& cache, bool verify_checksums)
      : reader_(&reader), cache_(&cache), verify_checksums_(verify_checksums) {}

  const StoreReader& reader() const { return *reader_; }
  const PageCache& cache() const { return *cache_; }
  bool verify_checksums() const { return verify_checksums_; }
  // The name leaf and page errors carry (the page store's).
  const std::string& store_name() const { return reader_->pages().name(); }

  // Pins leaf `leaf`'s pages (a cache lookup each, added to *stats if non-null), parses them into
  // out->view (releasing what *out held first; its buffers are reused) and checks the entries against the
  // tree and the object table (ReadLeaf, CheckLeafEntries). Errors name the store and the page; on error
  // *out holds nothing.
  Status Read(uint32_t leaf, QueryStats* stats, PinnedLeaf* out) const;
  // The same, into a new PinnedLeaf.
  Result<PinnedLeaf> Read(uint32_t leaf, QueryStats* stats) const;
  // Read, with out->decoded the leaf's DecodedLeaf: the one cached with its first page if it was built
  // from the pages now cached (then out->view stays empty: ParsePinned fills it), else one built now.
  Status ReadDecoded(uint32_t leaf, QueryStats* stats, PinnedLeaf* out) const;
  // ReadDecoded's warm path: if every page of the leaf is cached (and, with verify_checksums, verified),
  // reads it as ReadDecoded does and returns true; else returns false having pinned and counted nothing.
  // On an error out->pages stay pinned for the caller to release.
  Result<bool> ReadCachedDecoded(uint32_t leaf, QueryStats* stats, PinnedLeaf* out) const;
  // Parses out->view from its pinned pages if it is empty (after a ReadDecoded that took a cached
  // DecodedLeaf): the bytes checked when the DecodedLeaf was built, so the same entries in the same order.
  Status ParsePinned(PinnedLeaf* out) const;

  // From leaves[0] on, up to kMaxVisited leaves whose pages are all cached (and, with verify_checksums,
  // verified) and whose first page carries the DecodedLeaf built from those very copies: calls `use` once
  // with their DecodedLeafs in order, under the cache's lock and without pinning them. The counts and the
  // LRU order are those of reading the leaves one at a time (PageCache::VisitCachedRuns). `use` must not
  // call into the cache; the DecodedLeafs are valid only during it. Returns how many leaves `use` got: 0
  // (nothing counted, `use` not called) when leaves[0] is not such a leaf or `leaves` is empty.
  size_t VisitCachedDecoded(std::span<const uint32_t> leaves, QueryStats* stats,
                            CallbackRef<void(std::span<const DecodedLeaf* const>)> use) const;

  // The mesh of one of the store's entries (DecodeStoredMesh).
  Status DecodeMesh(const ObjectEntryView& entry, Mesh* mesh) const;

 private:
  const StoreReader* reader_;
  PageCache* cache_;
  bool verify_checksums_;
};

// DecodeObjectMesh with the store's dictionary (StoreReader::options().codec.dictionary), naming the
// store in its error (the entry's own checks cannot know the file).
Status DecodeStoredMesh(const StoreReader& store, const ObjectEntryView& entry, Mesh* mesh);

}  // namespace mktree
