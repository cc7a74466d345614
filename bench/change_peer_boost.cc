// Boost.Geometry peer of changes_bench: bgi::rtree<(box, id), rstar<16>> in RAM, built by the packing
// constructor from the tanker's boxes; a batch is insert (add), remove of the exact (box, id) value
// (remove), remove and insert (replace). Nothing is written anywhere: a commit is the changes alone.
#include <algorithm>
#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <boost/version.hpp>
#include <iterator>

#include "bench/change_engine.h"

namespace mktree::bench {
namespace {

namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;

using BPoint = bg::model::point<float, 3, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BBox, ObjectId>;
using BTree = bgi::rtree<BValue, bgi::rstar<16>>;

BBox ToBBox(const Box3f& b) {
  return BBox(BPoint(b.min[0], b.min[1], b.min[2]), BPoint(b.max[0], b.max[1], b.max[2]));
}

class BoostChangeEngine : public ChangeEngine {
 public:
  std::string name() const override { return "bgi"; }
  std::string description() const override {
    return "Boost " BOOST_LIB_VERSION
           " Geometry rtree<(box, id), rstar<16>> (boxes only), packed, in RAM; "
           "commit = the inserts and removes (nothing durable)";
  }

  Status Load(const ChangeWorkload& w) override {
    std::vector<BValue> values;
    values.reserve(w.base_boxes.size());
    for (size_t id = 0; id < w.base_boxes.size(); ++id)
      values.emplace_back(ToBBox(w.base_boxes[id]), static_cast<ObjectId>(id));
    tree_ = std::make_unique<BTree>(values.begin(), values.end());
    return Status::Ok();
  }

  Status Stage(const ChangeBatchScript& batch) override {
    batch_ = &batch;
    return Status::Ok();
  }

  Status Commit() override {
    for (const Change& c : batch_->changes) {
      if (c.kind != ChangeKind::kAdd && tree_->remove(BValue(ToBBox(c.old_box), c.id)) != 1)
        return Status::Internal("boost rtree: object " + std::to_string(c.id) + " not found");
      if (c.kind != ChangeKind::kRemove) tree_->insert(BValue(ToBBox(c.box), c.id));
    }
    return Status::Ok();
  }

  Status Query(const Box3f& box, std::vector<ObjectId>* ids) override {
    std::vector<BValue> found;
    tree_->query(bgi::intersects(ToBBox(box)), std::back_inserter(found));
    ids->clear();
    for (const BValue& v : found) ids->push_back(v.second);
    std::sort(ids->begin(), ids->end());
    return Status::Ok();
  }

 private:
  std::unique_ptr<BTree> tree_;
  const ChangeBatchScript* batch_ = nullptr;
};

}  // namespace

std::unique_ptr<ChangeEngine> MakeBoostChangeEngine() { return std::make_unique<BoostChangeEngine>(); }

}  // namespace mktree::bench
