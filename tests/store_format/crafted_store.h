// Crafted stores: what a user who tampers with a store can make, since checksums are not a MAC. A store
// is held whole (pages and all) as a StoreImage, changed in RAM, and written through the backend writers
// (engine/store_format/store_backend.h), which checksum whatever they are given: StoreWriter::Commit's
// validation is bypassed, so only StoreReader::Open and the leaf reads stand between such a store and an
// answer.
#pragma once

#include <cstdio>
#include <ostream>
#include <string>
#include <vector>

#include "engine/store_format/store_backend.h"
#include "engine/store_format/store_file.h"
#include "engine/tree/tree_stats.h"
#include "storage/atomic_file.h"
#include "storage/byte_io.h"
#include "storage/memory_page_store.h"
#include "storage/page_codec.h"
#include "store_format/store_test_util.h"

namespace mktree {

// Names a Backend test parameter ("pagefile", "hdf5") in test output.
inline void PrintTo(Backend b, std::ostream* os) { *os << BackendName(b); }

namespace testing {

struct StoreImage {
  StoreContents contents;
  std::vector<std::vector<uint8_t>> pages;
  std::vector<uint32_t> object_leaf;  // each object's leaf, as SetObjectRecords writes it in the records

  MKTree& tree() { return contents.tree; }
  ObjectTable& objects() { return contents.objects; }
  uint64_t mem_page() const { return contents.params.mem_page(); }
};

// The store at `path`, read whole.
inline Result<StoreImage> LoadStoreImage(const std::string& path) {
  auto r = StoreReader::Open(path);
  if (!r.ok()) return r.status();
  const StoreReader& s = **r;
  StoreImage img;
  img.contents.params = s.options().params;
  img.contents.codec = s.options().codec;
  img.contents.tree = s.tree();
  img.contents.tree.leaf_filter_begin.clear();  // derived at open
  img.contents.objects = s.objects();
  img.contents.stats_json = s.stats_json();
  for (ObjectId id = 0; id < s.object_count(); ++id) {
    auto leaf = s.ObjectLeaf(id);
    if (!leaf.ok()) return leaf.status();
    img.object_leaf.push_back(*leaf);
  }
  img.pages.resize(s.pages().page_count());
  for (uint64_t i = 0; i < img.pages.size(); ++i) {
    img.pages[i].resize(s.pages().page_bytes());
    MKTREE_RETURN_IF_ERROR(s.pages().ReadPage(i, img.pages[i].data()));
  }
  return img;
}

// Writes `image` as a store at `path` (replacing it), with valid checksums and no structural check.
inline Status WriteStoreImage(const StoreImage& image, const std::string& path, Backend backend) {
  const std::string temp = AtomicTempPath(path);
  auto w = backend == Backend::kHdf5 ? CreateHdf5Writer(temp, image.contents.params, DefaultFileOps())
                                     : CreatePagedFileWriter(temp, image.contents.params, DefaultFileOps());
  if (!w.ok()) return w.status();
  for (uint64_t i = 0; i < image.pages.size(); ++i)
    MKTREE_RETURN_IF_ERROR((*w)->pages().WritePage(i, image.pages[i].data()));
  MKTREE_RETURN_IF_ERROR((*w)->Finish(image.contents));
  w->reset();
  bool renamed = false;
  return RenameOverTarget(temp, path, DefaultFileOps(), path, &renamed);
}

// Replaces the image's object record pages (the pages after its leaf pages) and sources by records of
// `objects` (box from the mesh, name, source, attributes, leaf from img->object_leaf), as
// StoreWriter::AppendObject writes them.
inline Status SetObjectRecords(StoreImage* img, const std::vector<SceneObject>& objects) {
  ObjectTable& t = img->objects();
  img->pages.resize(img->pages.size() - t.record_directory.size());
  t.sources.clear();
  std::vector<uint8_t> record;
  RecordPager pager(img->mem_page(), [&](const uint8_t* page) {
    img->pages.emplace_back(page, page + img->mem_page());
    return Status::Ok();
  });
  for (const SceneObject& o : objects) {
    uint32_t source = 0;
    while (source < t.sources.size() && t.sources[source] != o.source) ++source;
    if (source == t.sources.size()) t.sources.push_back(o.source);
    record.clear();
    const uint32_t leaf = o.id < img->object_leaf.size() ? img->object_leaf[o.id] : kRecordNoLeaf;
    MKTREE_RETURN_IF_ERROR(EncodeRecord(o.Aabb(), source, leaf, o.name, o.attributes, &record));
    MKTREE_RETURN_IF_ERROR(pager.Add(o.id, record));
  }
  MKTREE_RETURN_IF_ERROR(pager.Finish());
  t.record_directory = pager.TakeDirectory();
  return Status::Ok();
}

// A store of `objects` packed by BuildTestStore, with the statistics the builder would write, as an image.
inline Result<StoreImage> MakeTestImage(const std::vector<SceneObject>& objects,
                                        const BuildParams& params = {}, Codec codec = Codec::kZstd) {
  StoreImage img;
  img.contents.params = params;
  img.contents.codec.codec = codec;
  MemoryPageStore pages(params.mem_page());
  BuiltStore built;
  MKTREE_RETURN_IF_ERROR(BuildTestStore(objects, img.contents.codec, params, &pages, &built));
  img.contents.tree = std::move(built.tree);
  img.contents.objects = built.objects;
  img.object_leaf = built.object_leaf;
  img.contents.stats_json = ComputeTreeStats(img.contents.tree, objects.size(), {}).ToJson();
  img.pages.resize(pages.page_count());
  for (uint64_t i = 0; i < img.pages.size(); ++i)
    img.pages[i].assign(pages.mutable_page(i), pages.mutable_page(i) + params.mem_page());
  MKTREE_RETURN_IF_ERROR(SetObjectRecords(&img, objects));
  return img;
}
// The same for MakeObjects(n, seed): prisms, boxes, random meshes, and multi-page leaves.
inline Result<StoreImage> MakeTestImage(uint32_t n, uint32_t seed) {
  return MakeTestImage(MakeObjects(n, seed));
}

// Re-seals a page after its bytes were edited: its header's fields are kept, its checksum recomputed.
inline void ResealPage(std::vector<uint8_t>* page) {
  auto h = CheckPage(page->data(), page->size(), false, "crafting", 0);
  if (h.ok()) SealPage(*h, page->data(), page->size());
}

// The offsets, within the page, of the entries of a single-page leaf's page.
inline std::vector<size_t> EntryOffsets(const std::vector<uint8_t>& page) {
  std::vector<size_t> out;
  const uint8_t* payload = page.data() + kPageHeaderBytes;
  const uint32_t count = storage_internal::Get<uint32_t>(payload);
  const uint64_t total = storage_internal::Get<uint64_t>(payload + 8);
  uint64_t off = kLeafHeaderBytes;
  for (uint32_t i = 0; i < count && off < total; ++i) {
    auto e = ParseObjectEntry(payload + off, total - off);
    if (!e.ok()) break;
    out.push_back(kPageHeaderBytes + off);
    off += e->entry_bytes();
  }
  return out;
}

// Gives every node and leaf the root's box and every internal node the overlap planes that go with it
// (a = min, b = max along its axis). The store stays valid, and the links of the tree can then be
// changed without a box check catching the change first. The leaf filter, quantized in the leaves'
// boxes, is dropped.
inline void FlattenBoxes(StoreImage* image) {
  MKTree& t = image->tree();
  if (t.nodes.empty()) return;
  const Box3f root = t.nodes[0].box;
  for (TreeNode& n : t.nodes) {
    n.box = root;
    if (!n.is_leaf()) {
      n.a = root.min[n.axis];
      n.b = root.max[n.axis];
    }
  }
  for (LeafInfo& l : t.leaves) l.box = root;
  t.leaf_filter.clear();
}

// The index of an internal node both of whose children are leaves.
inline uint32_t NodeWithTwoLeaves(const MKTree& t) {
  for (uint32_t i = 0; i < t.nodes.size(); ++i) {
    const TreeNode& n = t.nodes[i];
    if (!n.is_leaf() && t.nodes[n.child[0]].is_leaf() && t.nodes[n.child[1]].is_leaf()) return i;
  }
  return kNoIndex;
}

// The first single-page leaf with at least `min_objects` objects.
inline uint32_t LeafWithObjects(const MKTree& t, uint32_t min_objects) {
  for (uint32_t l = 0; l < t.leaves.size(); ++l)
    if (t.leaves[l].page_count == 1 && t.leaves[l].object_count >= min_objects) return l;
  return kNoIndex;
}

}  // namespace testing
}  // namespace mktree
