// libspatialindex peer of changes_bench: an R*-tree of the objects' boxes (no data blobs) in the disk
// storage manager with 12 KiB pages and no buffer (node reads and writes go through its fstreams, the OS
// page cache between them and the disk; its RandomEvictionsBuffer evicts at random, see
// peer_spatialindex.cc). Load bulk-loads the tanker's boxes (STR); a batch is insertData (add), deleteData
// (remove), deleteData and insertData (replace), then the commit: RTree::flush (the header), the storage
// manager's flush (its page map and the fstreams) and fdatasync of both files. libspatialindex has no
// transactions: nodes are rewritten in place, so a crash within a commit can leave a torn tree.
#include <fcntl.h>
#include <spatialindex/SpatialIndex.h>
#include <spatialindex/Version.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>

#include "bench/change_engine.h"
#include "bench/peer_engine.h"

namespace mktree::bench {
namespace {

namespace si = SpatialIndex;

// Node bytes of libspatialindex: 12 header + 48 MBR, and 60 per entry (48 box, 8 id, 4 data length).
constexpr uint32_t kNodeCapacity = (kPageBytes - 60) / 60;
// libspatialindex has one fill factor for two things: how full the bulk loader packs nodes, and the fill
// below which a deletion dissolves a node and reinserts its entries. Bulk-loaded at its default 0.7, every
// leaf sits at that minimum and its first deletion reinserts all its entries (about 12 ms a change at 1M),
// and nodes its R*-tree splits (40/60 %) start below it. So the tree is bulk-loaded at 0.7 and then the
// minimum is set to 0.4 (the R*-tree's m = 40 % of M) in the tree's header, which has no setter.
constexpr double kBulkFillFactor = 0.7;
constexpr double kMinFillFactor = 0.4;
// The header's layout (RTree::storeHeader): root id (8 bytes), variant (4), then the fill factor (double).
constexpr size_t kHeaderFillFactorOffset = sizeof(si::id_type) + sizeof(si::RTree::RTreeVariant);

si::Region ToRegion(const Box3f& b) {
  const double lo[3] = {b.min[0], b.min[1], b.min[2]}, hi[3] = {b.max[0], b.max[1], b.max[2]};
  return si::Region(lo, hi, 3);
}

// The tanker's boxes as a bulk-load stream, in id order.
class BoxStream : public si::IDataStream {
 public:
  explicit BoxStream(const std::vector<Box3f>* boxes) : boxes_(boxes) {}
  si::IData* getNext() override {
    if (next_ >= boxes_->size()) return nullptr;
    si::Region r = ToRegion((*boxes_)[next_]);
    auto* d = new si::RTree::Data(0, nullptr, r, static_cast<si::id_type>(next_));
    ++next_;
    return d;
  }
  bool hasNext() override { return next_ < boxes_->size(); }
  uint32_t size() override { return static_cast<uint32_t>(boxes_->size()); }
  void rewind() override { next_ = 0; }

 private:
  const std::vector<Box3f>* boxes_;
  size_t next_ = 0;
};

class IdCollector : public si::IVisitor {
 public:
  explicit IdCollector(std::vector<ObjectId>* ids) : ids_(ids) {}
  void visitNode(const si::INode&) override {}
  void visitData(const si::IData& d) override { ids_->push_back(static_cast<ObjectId>(d.getIdentifier())); }
  void visitData(std::vector<const si::IData*>& v) override {
    for (const si::IData* d : v) visitData(*d);
  }

 private:
  std::vector<ObjectId>* ids_;
};

class SpatialIndexChangeEngine : public ChangeEngine {
 public:
  explicit SpatialIndexChangeEngine(const std::string& dir) : base_(dir + "/changes_spatialindex") {}
  ~SpatialIndexChangeEngine() override {
    Close();
    std::filesystem::remove(base_ + ".dat");
    std::filesystem::remove(base_ + ".idx");
  }

  std::string name() const override { return "spatialindex"; }
  std::string description() const override {
    return std::string("libspatialindex ") + SIDX_RELEASE_NAME + " R*-tree (boxes only), STR bulk load, " +
           "capacity " + std::to_string(kNodeCapacity) +
           ", nodes 70 % full, minimum fill 40 %, disk storage manager with " +
           std::to_string(kPageBytes / 1024) + " KiB pages and no buffer; commit = flush + fdatasync (no " +
           "transactions)";
  }

  Status Load(const ChangeWorkload& w) override {
    Close();
    try {
      std::string base = base_;
      disk_.reset(si::StorageManager::createNewDiskStorageManager(base, kPageBytes));
      BoxStream stream(&w.base_boxes);
      si::id_type index_id = 0;
      tree_.reset(si::RTree::createAndBulkLoadNewRTree(si::RTree::BLM_STR, stream, *disk_, kBulkFillFactor,
                                                       kNodeCapacity, kNodeCapacity, 3, si::RTree::RV_RSTAR,
                                                       index_id));
      tree_.reset();  // stores the header
      MKTREE_RETURN_IF_ERROR(SetMinFill(index_id));
      tree_.reset(si::RTree::loadRTree(*disk_, index_id));
      Tools::PropertySet properties;
      tree_->getIndexProperties(properties);
      if (properties.getProperty("FillFactor").m_val.dblVal != kMinFillFactor)
        return Status::Internal("libspatialindex: the header's fill factor did not take");
    } catch (Tools::Exception& e) {
      return Status::Internal("libspatialindex load: " + e.what());
    }
    for (const char* suffix : {".dat", ".idx"}) {
      const int fd = open((base_ + suffix).c_str(), O_RDWR | O_CLOEXEC);
      if (fd < 0) return Status::IOError("libspatialindex: cannot open " + base_ + suffix);
      fds_.push_back(fd);
    }
    return Commit();
  }

  Status Stage(const ChangeBatchScript& batch) override {
    batch_ = &batch;
    return Status::Ok();
  }

  Status Commit() override {
    try {
      if (batch_) {
        for (const Change& c : batch_->changes) {
          if (c.kind != ChangeKind::kAdd && !tree_->deleteData(ToRegion(c.old_box), c.id))
            return Status::Internal("libspatialindex: object " + std::to_string(c.id) + " not found");
          if (c.kind != ChangeKind::kRemove) tree_->insertData(0, nullptr, ToRegion(c.box), c.id);
        }
      }
      tree_->flush();
      disk_->flush();
    } catch (Tools::Exception& e) {
      return Status::Internal("libspatialindex commit: " + e.what());
    }
    batch_ = nullptr;
    for (int fd : fds_)
      if (fdatasync(fd) != 0) return Status::IOError("libspatialindex: fdatasync of " + base_);
    return Status::Ok();
  }

  Status Query(const Box3f& box, std::vector<ObjectId>* ids) override {
    ids->clear();
    IdCollector visitor(ids);
    try {
      tree_->intersectsWithQuery(ToRegion(box), visitor);
    } catch (Tools::Exception& e) {
      return Status::Internal("libspatialindex query: " + e.what());
    }
    std::sort(ids->begin(), ids->end());
    return Status::Ok();
  }

 private:
  Status SetMinFill(si::id_type header_id) {
    uint32_t len = 0;
    uint8_t* header = nullptr;
    disk_->loadByteArray(header_id, len, &header);
    std::unique_ptr<uint8_t[]> owned(header);
    double fill = 0;
    if (len < kHeaderFillFactorOffset + sizeof fill) return Status::Internal("libspatialindex: short header");
    std::memcpy(&fill, header + kHeaderFillFactorOffset, sizeof fill);
    if (fill != kBulkFillFactor) return Status::Internal("libspatialindex: unexpected header layout");
    std::memcpy(header + kHeaderFillFactorOffset, &kMinFillFactor, sizeof fill);
    disk_->storeByteArray(header_id, len, header);
    return Status::Ok();
  }

  void Close() {
    tree_.reset();
    disk_.reset();
    for (int fd : fds_) close(fd);
    fds_.clear();
  }

  std::string base_;
  std::unique_ptr<si::IStorageManager> disk_;
  std::unique_ptr<si::ISpatialIndex> tree_;
  std::vector<int> fds_;
  const ChangeBatchScript* batch_ = nullptr;
};

}  // namespace

std::unique_ptr<ChangeEngine> MakeSpatialIndexChangeEngine(const std::string& dir) {
  return std::make_unique<SpatialIndexChangeEngine>(dir);
}

}  // namespace mktree::bench
