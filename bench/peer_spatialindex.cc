// libspatialindex 1.9 R*-tree peer: STR bulk load into the disk storage manager with 12 KiB pages, each
// leaf entry carrying the object's encoded geometry as its data blob (stored inline in the leaf node; a node
// larger than a page spills over consecutive pages of the storage manager).
//
// I/O is counted by CountingStorage, our own IStorageManager in front of the disk manager: every
// loadByteArray that reaches the disk manager costs max(1, ceil(len / page)) page reads (what the disk
// manager reads for that node). Warm runs put our own LRU of the same byte budget as mktree's cache in
// front; libspatialindex's RandomEvictionsBuffer is not used (it evicts at random and its counters mix
// hits with reads).
#include <spatialindex/SpatialIndex.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <list>
#include <unordered_map>

#include "bench/peer_engine.h"

namespace mktree::bench {
namespace {

namespace si = SpatialIndex;

uint64_t PagesOf(uint32_t len) { return std::max<uint64_t>(1, (len + kPageBytes - 1) / kPageBytes); }

// A serialized libspatialindex node starts with nodeType (1 index, 2 leaf) and level (0 = leaf), uint32.
// (The index header, stored through the same manager, is neither.)
bool NodeIs(const uint8_t* data, uint32_t len, uint32_t want_type) {
  if (len < 8) return false;
  uint32_t type, level;
  std::memcpy(&type, data, 4);
  std::memcpy(&level, data + 4, 4);
  return type == want_type && (type == 2) == (level == 0);
}
bool IsInnerNode(const uint8_t* data, uint32_t len) { return NodeIs(data, len, 1); }
bool IsLeafNode(const uint8_t* data, uint32_t len) { return NodeIs(data, len, 2); }

class CountingStorage : public si::IStorageManager {
 public:
  CountingStorage(si::IStorageManager* disk, uint64_t cache_pages) : disk_(disk), cache_pages_(cache_pages) {}

  void loadByteArray(const si::id_type id, uint32_t& len, uint8_t** data) override {
    if (cache_pages_ > 0) {
      auto it = cache_.find(id);
      if (it != cache_.end()) {
        lru_.splice(lru_.begin(), lru_, it->second.pos);
        const std::vector<uint8_t>& bytes = it->second.bytes;
        len = static_cast<uint32_t>(bytes.size());
        *data = new uint8_t[len];
        std::memcpy(*data, bytes.data(), len);
        return;
      }
    }
    disk_->loadByteArray(id, len, data);
    const uint64_t pages = PagesOf(len);
    io_.pages += pages;
    io_.bytes += len;
    if (IsInnerNode(*data, len)) io_.inner_pages += pages;
    if (cache_pages_ > 0 && pages <= cache_pages_) {
      lru_.push_front(id);
      cache_[id] = Cached{std::vector<uint8_t>(*data, *data + len), lru_.begin()};
      cached_pages_ += pages;
      while (cached_pages_ > cache_pages_) {
        auto victim = cache_.find(lru_.back());
        cached_pages_ -= PagesOf(static_cast<uint32_t>(victim->second.bytes.size()));
        cache_.erase(victim);
        lru_.pop_back();
      }
    }
  }
  void storeByteArray(si::id_type& id, const uint32_t len, const uint8_t* const data) override {
    Forget(id);
    disk_->storeByteArray(id, len, data);
    written_[id] = {PagesOf(len), IsLeafNode(data, len)};
  }
  void deleteByteArray(const si::id_type id) override {
    Forget(id);
    written_.erase(id);
    disk_->deleteByteArray(id);
  }
  void flush() override { disk_->flush(); }

  Io TakeIo() {
    Io io = io_;
    io_ = Io();
    return io;
  }
  void Clear() {
    cache_.clear();
    lru_.clear();
    cached_pages_ = 0;
  }
  // Pages held by leaf nodes among everything stored (build statistics).
  uint64_t LeafPages() const {
    uint64_t n = 0;
    for (const auto& [id, w] : written_) n += w.leaf ? w.pages : 0;
    return n;
  }
  uint64_t LeafNodes() const {
    uint64_t n = 0;
    for (const auto& [id, w] : written_) n += w.leaf;
    return n;
  }
  uint64_t AllPages() const {
    uint64_t n = 0;
    for (const auto& [id, w] : written_) n += w.pages;
    return n;
  }

 private:
  struct Cached {
    std::vector<uint8_t> bytes;
    std::list<si::id_type>::iterator pos;
  };
  struct Written {
    uint64_t pages = 0;
    bool leaf = false;
  };
  void Forget(si::id_type id) {
    auto it = cache_.find(id);
    if (it == cache_.end()) return;
    cached_pages_ -= PagesOf(static_cast<uint32_t>(it->second.bytes.size()));
    lru_.erase(it->second.pos);
    cache_.erase(it);
  }

  si::IStorageManager* disk_;
  uint64_t cache_pages_;
  uint64_t cached_pages_ = 0;
  std::unordered_map<si::id_type, Cached> cache_;
  std::list<si::id_type> lru_;
  std::unordered_map<si::id_type, Written> written_;
  Io io_;
};

// Streams the scene into the bulk loader, one RTree::Data (AABB + encoded entry) at a time.
class SceneStream : public si::IDataStream {
 public:
  SceneStream(const SceneSpec& scene, const CodecOptions& codec) : scene_(scene), codec_(codec) { rewind(); }

  si::IData* getNext() override {
    if (!has_next_) return nullptr;
    const Box3f b = obj_.Aabb();
    double lo[3], hi[3];
    for (int i = 0; i < 3; ++i) {
      lo[i] = b.min[i];
      hi[i] = b.max[i];
    }
    si::Region r(lo, hi, 3);
    entry_.clear();
    EncodePeerEntry(obj_, codec_, &entry_);
    auto* d = new si::RTree::Data(static_cast<uint32_t>(entry_.size()), entry_.data(), r, obj_.id);
    ++count_;
    Advance();
    return d;
  }
  bool hasNext() override { return has_next_; }
  uint32_t size() override { throw Tools::NotSupportedException("SceneStream::size"); }
  void rewind() override {
    auto src = scene_.Open(0);
    if (!src.ok()) throw Tools::IllegalStateException(src.status().ToString());
    source_ = std::move(*src);
    count_ = 0;
    Advance();
  }
  uint64_t count() const { return count_; }

 private:
  void Advance() {
    auto more = source_->Next(&obj_);
    if (!more.ok()) throw Tools::IllegalStateException(more.status().ToString());
    has_next_ = *more;
  }
  SceneSpec scene_;
  CodecOptions codec_;
  std::unique_ptr<SceneSource> source_;
  SceneObject obj_;
  std::vector<uint8_t> entry_;
  bool has_next_ = false;
  uint64_t count_ = 0;
};

class IdVisitor : public si::IVisitor {
 public:
  explicit IdVisitor(std::vector<ObjectId>* hits) : hits_(hits) {}
  void visitNode(const si::INode&) override {}
  void visitData(const si::IData& d) override {
    // Read the geometry entry as mktree's AABB scan does (header parsed, id checked).
    uint32_t len = 0;
    uint8_t* data = nullptr;
    d.getData(len, &data);
    auto e = ParseObjectEntry(data, len);
    if (!e.ok() || e->id != static_cast<ObjectId>(d.getIdentifier())) bad_ = true;
    delete[] data;
    hits_->push_back(static_cast<ObjectId>(d.getIdentifier()));
  }
  void visitData(std::vector<const si::IData*>& v) override {
    for (const si::IData* d : v) visitData(*d);
  }
  bool bad() const { return bad_; }

 private:
  std::vector<ObjectId>* hits_;
  bool bad_ = false;
};

class SpatialIndexEngine : public Engine {
 public:
  SpatialIndexEngine(const std::string& dir, const CodecOptions& codec, uint32_t leaf_capacity,
                     uint32_t index_capacity)
      : base_(dir + "/peer_spatialindex"),
        codec_(codec),
        leaf_capacity_(leaf_capacity),
        index_capacity_(index_capacity) {}
  ~SpatialIndexEngine() override { Close(); }

  std::string name() const override { return "libspatialindex"; }
  std::vector<std::string> files() const override { return {base_ + ".dat", base_ + ".idx"}; }
  std::string cold_method() const override {
    return "no buffer; posix_fadvise(DONTNEED) on .dat/.idx before each query (its fstream reads are "
           "buffered)";
  }

  Status Build(const SceneSpec& scene, Facts* facts) override {
    try {
      std::string base = base_;
      std::unique_ptr<si::IStorageManager> disk(
          si::StorageManager::createNewDiskStorageManager(base, kPageBytes));
      CountingStorage counting(disk.get(), 0);
      SceneStream stream(scene, codec_);
      si::id_type index_id = 0;
      // fillFactor must lie in (0, 1); capacities are chosen so that floor(capacity * 0.99) is the
      // wanted fan-out (see CapacityFor in peers_bench.cc).
      std::unique_ptr<si::ISpatialIndex> tree(
          si::RTree::createAndBulkLoadNewRTree(si::RTree::BLM_STR, stream, counting, 0.99, index_capacity_,
                                               leaf_capacity_, 3, si::RTree::RV_RSTAR, index_id));
      tree.reset();
      counting.flush();
      (*facts)["index_id"] = static_cast<double>(index_id);
      (*facts)["objects"] = static_cast<double>(stream.count());
      (*facts)["leaf_nodes"] = static_cast<double>(counting.LeafNodes());
      (*facts)["leaf_pages"] = static_cast<double>(counting.LeafPages());
      (*facts)["pages"] = static_cast<double>(counting.AllPages());
      (*facts)["leaf_capacity"] = leaf_capacity_;
      (*facts)["index_capacity"] = index_capacity_;
    } catch (Tools::Exception& e) {
      return Status::Internal("libspatialindex build: " + e.what());
    } catch (std::exception& e) {
      return Status::Internal(std::string("libspatialindex build: ") + e.what());
    }
    return Status::Ok();
  }

  Status Open(bool warm, const Facts& facts) override {
    Close();
    try {
      std::string base = base_;
      disk_.reset(si::StorageManager::loadDiskStorageManager(base));
      counting_ = std::make_unique<CountingStorage>(disk_.get(), warm ? kWarmCacheBytes / kPageBytes : 0);
      tree_.reset(si::RTree::loadRTree(*counting_, static_cast<si::id_type>(facts.at("index_id"))));
    } catch (Tools::Exception& e) {
      return Status::IOError("libspatialindex open: " + e.what());
    }
    counting_->TakeIo();
    return Status::Ok();
  }
  void Close() override {
    tree_.reset();
    counting_.reset();
    disk_.reset();
  }
  void ClearCache() override { counting_->Clear(); }

  Status Run(const Query& q, std::vector<ObjectId>* hits, Io* io) override {
    hits->clear();
    counting_->TakeIo();
    double lo[3], hi[3];
    for (int i = 0; i < 3; ++i) {
      lo[i] = q.kind == Query::Kind::kPoint ? q.point[i] : q.box.min[i];
      hi[i] = q.kind == Query::Kind::kPoint ? q.point[i] : q.box.max[i];
    }
    IdVisitor visitor(hits);
    try {
      tree_->intersectsWithQuery(si::Region(lo, hi, 3), visitor);
    } catch (Tools::Exception& e) {
      return Status::IOError("libspatialindex query: " + e.what());
    }
    if (visitor.bad()) return Status::Corruption("libspatialindex: a data blob is not the object's entry");
    std::sort(hits->begin(), hits->end());
    *io = counting_->TakeIo();
    return Status::Ok();
  }

  double objects_per_page(const Facts& facts) const override {
    return facts.at("objects") / std::max(1.0, facts.at("leaf_pages"));
  }

 private:
  std::string base_;
  CodecOptions codec_;
  uint32_t leaf_capacity_, index_capacity_;
  std::unique_ptr<si::IStorageManager> disk_;
  std::unique_ptr<CountingStorage> counting_;
  std::unique_ptr<si::ISpatialIndex> tree_;
};

}  // namespace

std::unique_ptr<Engine> MakeSpatialIndexEngine(const std::string& dir, const CodecOptions& codec,
                                               uint32_t leaf_capacity, uint32_t index_capacity) {
  return std::make_unique<SpatialIndexEngine>(dir, codec, leaf_capacity, index_capacity);
}

}  // namespace mktree::bench
