#include "engine/store_format/leaf_source.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace mktree {

Status LeafSource::Read(uint32_t leaf, QueryStats* stats, PinnedLeaf* out) const {
  const MKTree& tree = reader_->tree();
  return ReadLeaf(*cache_, store_name(), leaf, tree.leaves[leaf], reader_->objects(), tree.params.mem_page(),
                  verify_checksums_, stats, out);
}

Result<PinnedLeaf> LeafSource::Read(uint32_t leaf, QueryStats* stats) const {
  PinnedLeaf out;
  MKTREE_RETURN_IF_ERROR(Read(leaf, stats, &out));
  return out;
}

Status LeafSource::ReadDecoded(uint32_t leaf, QueryStats* stats, PinnedLeaf* out) const {
  const MKTree& tree = reader_->tree();
  return ReadLeaf(*cache_, store_name(), leaf, tree.leaves[leaf], reader_->objects(), tree.params.mem_page(),
                  verify_checksums_, stats, out, /*decode=*/true);
}

Result<bool> LeafSource::ReadCachedDecoded(uint32_t leaf, QueryStats* stats, PinnedLeaf* out) const {
  const MKTree& tree = reader_->tree();
  return ReadCachedLeaf(*cache_, store_name(), leaf, tree.leaves[leaf], reader_->objects(),
                        tree.params.mem_page(), verify_checksums_, stats, out, /*decode=*/true);
}

Status LeafSource::ParsePinned(PinnedLeaf* out) const {
  return mktree::ParsePinned(store_name(), reader_->tree().params.mem_page(), out);
}

size_t LeafSource::VisitCachedDecoded(std::span<const uint32_t> leaves, QueryStats* stats,
                                      CallbackRef<void(std::span<const DecodedLeaf* const>)> use) const {
  const MKTree& tree = reader_->tree();
  PageCache::PageRun runs[kMaxVisited];
  const size_t m = std::min(leaves.size(), kMaxVisited);
  if (m == 0) return 0;
  for (size_t k = 0; k < m; ++k) {
    const LeafInfo& info = tree.leaves[leaves[k]];
    runs[k] = {info.first_page, info.page_count};
  }
  // A leaf's first page carries only its DecodedLeaf, current if built from these copies of the others.
  auto current = [](const PageAttachment* a, std::span<const uint64_t> later_loads) {
    const std::vector<uint64_t>& built_from = static_cast<const DecodedLeaf*>(a)->later_page_loads();
    return std::equal(built_from.begin(), built_from.end(), later_loads.begin(), later_loads.end());
  };
  auto visit = [&](std::span<const PageAttachment* const> attached) {
    const DecodedLeaf* decoded[kMaxVisited];
    for (size_t k = 0; k < attached.size(); ++k) decoded[k] = static_cast<const DecodedLeaf*>(attached[k]);
    use(std::span<const DecodedLeaf* const>(decoded, attached.size()));
  };
  return cache_->VisitCachedRuns(std::span<const PageCache::PageRun>(runs, m), verify_checksums_, current,
                                 visit, stats);
}

Status LeafSource::DecodeMesh(const ObjectEntryView& entry, Mesh* mesh) const {
  return DecodeStoredMesh(*reader_, entry, mesh);
}

Status DecodeStoredMesh(const StoreReader& store, const ObjectEntryView& entry, Mesh* mesh) {
  Status st = DecodeObjectMesh(entry, mesh, store.options().codec.dictionary.get());
  return st.ok() ? st : Status::Corruption(store.path() + ": " + st.message());
}

}  // namespace mktree
