#include "engine/store_format/leaf_reader.h"

#include <algorithm>
#include <cstddef>
#include <limits>
#include <new>

#include "engine/store_format/tree_codec.h"
#include "storage/page_codec.h"

namespace mktree {

Status CheckLeafEntries(const LeafView& view, const std::string& store_name, uint32_t leaf,
                        const LeafInfo& info, const ObjectTable& objects, std::vector<uint64_t>* seen) {
  auto fail = [&](const std::string& what) {
    return Status::Corruption(store_name + ": page " + std::to_string(info.first_page) + " (leaf " +
                              std::to_string(leaf) + "): " + what);
  };
  if (view.payload_bytes() != info.payload_bytes)
    return fail("holds a payload of " + std::to_string(view.payload_bytes()) + " bytes but the tree says " +
                std::to_string(info.payload_bytes));
  if (view.size() != info.object_count)
    return fail("holds " + std::to_string(view.size()) + " objects but the tree says " +
                std::to_string(info.object_count));
  if (leaf >= objects.leaf_digest.size())
    return fail("no id digest for this leaf (" + std::to_string(objects.leaf_digest.size()) + " leaves)");
  const uint64_t n_objects = objects.size();
  // Duplicates: one bit per object id, set as ids are met and cleared (whole words: every bit set is
  // one of this leaf's) before returning, so that it is all zero between calls. Unlike sorting the ids,
  // this costs a few cache hits per entry.
  const size_t words = (n_objects + 63) / 64;
  if (seen->size() < words) seen->resize(words, 0);
  uint64_t* bits = seen->data();
  const std::vector<ObjectEntryView>& entries = view.entries();
  size_t i = 0;
  uint64_t digest = 0;
  std::string problem;
  for (; i < entries.size(); ++i) {
    const ObjectEntryView& e = entries[i];
    if (e.id >= n_objects) {
      problem =
          "object " + std::to_string(e.id) + " out of range (" + std::to_string(n_objects) + " objects)";
      break;
    }
    if (!BoxWithin(e.box, info.box)) {
      problem = "object " + std::to_string(e.id) + " lies outside the leaf's box";
      break;
    }
    uint64_t& word = bits[e.id >> 6];
    const uint64_t bit = uint64_t{1} << (e.id & 63);
    if (word & bit) {
      problem = "object " + std::to_string(e.id) + " appears twice";
      break;
    }
    word |= bit;
    digest += ObjectIdHash(e.id);
  }
  for (size_t j = 0; j < i; ++j) bits[entries[j].id >> 6] = 0;
  if (problem.empty() && digest != objects.leaf_digest[leaf])
    problem = "its objects are not the ones the object table puts in it (id digest mismatch)";
  if (!problem.empty()) return fail(problem);
  // The digest matched, but for a crafted collision: no id may be another leaf's too.
  if (objects.claims.Claimed(leaf)) return Status::Ok();
  thread_local std::vector<uint32_t> ids;
  ids.clear();
  for (const ObjectEntryView& e : entries) ids.push_back(e.id);
  const uint64_t twice = objects.claims.Claim(leaf, objects.leaf_digest.size(), n_objects, ids);
  if (twice == LeafClaims::kNone) return Status::Ok();
  return fail("object " + std::to_string(twice) +
              " is in two leaves, this one and one read before (their id digests were made to collide)");
}

void DecodedLeaf::FreeBlock::operator()(void* p) const { ::operator delete (p, std::align_val_t{64}); }

DecodedLeaf::DecodedLeaf(const LeafView& view, uint64_t mesh_budget, std::vector<uint64_t> later_page_loads)
    : later_page_loads_(std::move(later_page_loads)), mesh_budget_(mesh_budget) {
  const size_t n = view.size();
  size_ = n;
  padded_ = (n + kLanes - 1) / kLanes * kLanes;
  static_assert(sizeof(float) == sizeof(ObjectId));
  const size_t bytes = 7 * padded_ * sizeof(float) + n;
  block_.reset(::operator new (std::max<size_t>(bytes, 1), std::align_val_t{64}));
  boxes_ = static_cast<float*>(block_.get());
  ids_ = reinterpret_cast<ObjectId*>(static_cast<std::byte*>(block_.get()) + 6 * padded_ * sizeof(float));
  shape_flags_ = reinterpret_cast<uint8_t*>(ids_ + padded_);
  const float inf = std::numeric_limits<float>::infinity();
  for (int p = 0; p < 6; ++p) {
    float* plane = boxes_ + static_cast<size_t>(p) * padded_;
    for (size_t i = 0; i < n; ++i) {
      const Box3f& b = view.entry(i).box;
      plane[i] = p < 3 ? b.min[p] : b.max[p - 3];
    }
    // Padding meets nothing: a min of +inf is above every rounded query max (at most FLT_MAX).
    std::fill(plane + n, plane + padded_, p < 3 ? inf : -inf);
  }
  for (size_t i = 0; i < n; ++i) {
    const ObjectEntryView& e = view.entry(i);
    ids_[i] = e.id;
    shape_flags_[i] = e.shape_flags;
    for (int a = 0; a < 3; ++a) boxes_ordered_ = boxes_ordered_ && e.box.min[a] <= e.box.max[a];
  }
  std::fill(ids_ + n, ids_ + padded_, ObjectId{0});
  meshes_ = std::make_unique<std::atomic<const Mesh*>[]>(n);
  for (size_t i = 0; i < n; ++i) meshes_[i].store(nullptr, std::memory_order_relaxed);
}

DecodedLeaf::~DecodedLeaf() {
  for (size_t i = 0; i < size_; ++i) delete meshes_[i].load(std::memory_order_relaxed);
}

void DecodedLeaf::Prefetch(bool boxes) const {
  const char* from = reinterpret_cast<const char*>(boxes ? static_cast<const void*>(boxes_)
                                                         : static_cast<const void*>(ids_));
  const char* to = reinterpret_cast<const char*>(ids_ + size_);
  for (const char* p = from; p < to; p += 64) __builtin_prefetch(p);
}

namespace {
uint64_t MeshBytes(const Mesh& m) {
  return sizeof(Mesh) + m.vertices.size() * sizeof(double) + m.triangles.size() * sizeof(uint32_t);
}
}  // namespace

const Mesh* DecodedLeaf::CacheMesh(size_t i, Mesh&& mesh) const {
  if (const Mesh* m = this->mesh(i)) return m;
  const uint64_t bytes = MeshBytes(mesh);
  uint64_t used = mesh_bytes_.load(std::memory_order_relaxed);
  do {
    if (used + bytes > mesh_budget_) return nullptr;
  } while (!mesh_bytes_.compare_exchange_weak(used, used + bytes, std::memory_order_relaxed));
  auto owned = std::make_unique<Mesh>(std::move(mesh));
  const Mesh* expected = nullptr;
  if (meshes_[i].compare_exchange_strong(expected, owned.get(), std::memory_order_acq_rel,
                                         std::memory_order_acquire))
    return owned.release();
  mesh_bytes_.fetch_sub(bytes, std::memory_order_relaxed);  // another thread cached it first
  return expected;
}

uint64_t DecodedLeaf::bytes() const {
  return sizeof(*this) + 7 * padded_ * sizeof(float) + size_ +
         later_page_loads_.capacity() * sizeof(uint64_t) + size_ * sizeof(std::atomic<const Mesh*>) +
         mesh_bytes_.load(std::memory_order_relaxed);
}

Status ParsePinned(const std::string& store_name, uint64_t mem_page, PinnedLeaf* out) {
  if (out->view.size() != 0 || out->pages.empty()) return Status::Ok();
  return LeafView::Parse(store_name, out->leaf, out->first_page, out->page_data, mem_page, false, &out->view);
}

namespace {

// ReadLeaf after its pages are pinned in out->pages: checksums, then the cached DecodedLeaf or a parse,
// check and decode. On an error the pages stay pinned.
Status FinishPinned(const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                    const ObjectTable& objects, uint64_t mem_page, bool verify_checksums, PinnedLeaf* out,
                    bool decode) {
  out->page_data.clear();
  for (size_t k = 0; k < out->pages.size(); ++k) {
    PageHandle& h = out->pages[k];
    if (verify_checksums && !h.verified()) {
      MKTREE_RETURN_IF_ERROR(CheckPage(h.data(), mem_page, true, store_name, info.first_page + k).status());
      h.MarkVerified();
    }
    out->page_data.push_back(h.data());
  }
  if (decode && !out->pages.empty()) {
    // Cached with the first page, and built from these very copies of the others: the entries were parsed
    // and checked then.
    if (const auto* d = static_cast<const DecodedLeaf*>(out->pages[0].attachment())) {
      bool same = d->later_page_loads().size() + 1 == out->pages.size();
      for (size_t k = 1; same && k < out->pages.size(); ++k)
        same = d->later_page_loads()[k - 1] == out->pages[k].load_id();
      if (same) {
        out->decoded = d;
        return Status::Ok();
      }
    }
  }
  // Checksums are settled above; Parse still checks every header and entry.
  Status st = LeafView::Parse(store_name, leaf, info.first_page, out->page_data, mem_page, false, &out->view);
  if (st.ok()) st = CheckLeafEntries(out->view, store_name, leaf, info, objects, &out->seen);
  if (!st.ok()) {
    out->view.Clear();
    return st;
  }
  if (decode && out->pages.empty()) {  // a leaf of no pages (an empty tree's): nothing to cache
    static const DecodedLeaf* const kEmpty = new DecodedLeaf(LeafView(), 0, {});
    out->decoded = kEmpty;
  } else if (decode) {
    std::vector<uint64_t> loads;
    for (size_t k = 1; k < out->pages.size(); ++k) loads.push_back(out->pages[k].load_id());
    // A DecodedLeaf cached with an older copy of a later page is replaced: the first page's copy keeps one
    // attachment, so this one is used for this read only and the next read builds again. Rare (a later
    // page evicted before the first), and never wrong.
    auto built = std::make_unique<DecodedLeaf>(out->view, info.page_count * mem_page, std::move(loads));
    const DecodedLeaf* mine = built.get();
    const auto* kept = static_cast<const DecodedLeaf*>(out->pages[0].Attach(std::move(built)));
    out->decoded = mine;
    if (kept != mine) {
      // Another thread's, or a stale one: use a private copy this time.
      bool same = kept->later_page_loads().size() + 1 == out->pages.size();
      for (size_t k = 1; same && k < out->pages.size(); ++k)
        same = kept->later_page_loads()[k - 1] == out->pages[k].load_id();
      if (same) {
        out->decoded = kept;
      } else {
        thread_local std::unique_ptr<DecodedLeaf> t_private;
        std::vector<uint64_t> again;
        for (size_t k = 1; k < out->pages.size(); ++k) again.push_back(out->pages[k].load_id());
        t_private = std::make_unique<DecodedLeaf>(out->view, 0, std::move(again));
        out->decoded = t_private.get();
      }
    }
  }
  return Status::Ok();
}

}  // namespace

Status ReadLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf, const LeafInfo& info,
                const ObjectTable& objects, uint64_t mem_page, bool verify_checksums, QueryStats* stats,
                PinnedLeaf* out, bool decode) {
  out->Release();
  out->cache = &cache;
  out->leaf = leaf;
  out->first_page = info.first_page;
  // Each page pinned and checked before the next is pinned, so that an error leaves the later pages
  // unread.
  for (uint64_t p = info.first_page; p < info.first_page + info.page_count; ++p) {
    auto h = cache.Pin(p, stats);
    if (!h.ok()) {
      out->Release();
      return h.status();
    }
    if (verify_checksums && !h->verified()) {
      auto checked = CheckPage(h->data(), mem_page, true, store_name, p);
      if (!checked.ok()) {
        out->Release();
        return checked.status();
      }
      h->MarkVerified();
    }
    out->pages.push_back(std::move(*h));
  }
  Status st = FinishPinned(store_name, leaf, info, objects, mem_page, false, out, decode);
  if (!st.ok()) out->Release();
  return st;
}

Result<bool> ReadCachedLeaf(PageCache& cache, const std::string& store_name, uint32_t leaf,
                            const LeafInfo& info, const ObjectTable& objects, uint64_t mem_page,
                            bool verify_checksums, QueryStats* stats, PinnedLeaf* out, bool decode) {
  out->Release();
  out->cache = &cache;
  out->leaf = leaf;
  out->first_page = info.first_page;
  if (!cache.PinCached(info.first_page, info.page_count, verify_checksums, stats, &out->pages)) return false;
  MKTREE_RETURN_IF_ERROR(FinishPinned(store_name, leaf, info, objects, mem_page, false, out, decode));
  return true;
}

}  // namespace mktree
