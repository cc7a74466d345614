// The Database over one store that is already open: queries route through the store's MKtree and
// SplitTrees to the leaves they must read and read those through the store's LeafSource (its page cache
// and checks); clash runs on the same LeafSource. Database::Open opens the file and calls
// OpenStoreDatabase; a sharded store holds one per shard; tests open the StoreReader themselves to wrap
// its pages (StoreReader::WrapPages) before querying through it.
// Thread safety: as Database: every const method may run on many threads at once.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "engine/store_format/leaf_source.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"
#include "storage/page_cache.h"

namespace mktree {

class StoreDatabase final : public Database {
 public:
  StoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options);

  // The store's leaves through this database's page cache (what its queries and clashes read).
  const LeafSource& leaves() const { return leaves_; }
  const StoreReader& reader() const { return *reader_; }

  Result<bool> VisitUntil(const Query& q, const StoppableVisitor& visit, QueryStats* stats) const override;
  Status VisitSpans(const Query& q, const SpanVisitor& visit, QueryStats* stats) const override;
  using Database::RunBatchStreamed;
  Status RunBatchStreamed(const QuerySource& source, const BatchOptions& options,
                          const ResultVisitor& deliver) const override;
  Status SelfClash(const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats) const override;
  Status Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                 const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats) const override;
  Result<std::unique_ptr<NearestCursor>> OpenNearest(const DistanceQuery& query) const override;
  Result<bool> VisitRay(const RayQuery& query, const RayVisitor& visit, QueryStats* stats) const override;
  void ClearCache() override { cache_.Clear(); }
  const std::string& path() const override { return reader_->path(); }
  uint64_t object_count() const override { return reader_->object_count(); }
  Result<std::string> ObjectName(ObjectId id) const override;
  Result<ObjectRecord> Object(ObjectId id, QueryStats* stats = nullptr) const override;
  Result<Mesh> ObjectGeometry(ObjectId id, QueryStats* stats = nullptr) const override;
  Box3d bounds() const override { return reader_->tree().WorldBounds(); }
  double objects_per_page() const override;
  const std::string& stats_json() const override { return reader_->stats_json(); }

 private:
  std::unique_ptr<StoreReader> reader_;
  OpenOptions options_;
  mutable PageCache cache_;
  LeafSource leaves_;
};

std::unique_ptr<StoreDatabase> OpenStoreDatabase(std::unique_ptr<StoreReader> reader,
                                                 const OpenOptions& options);

}  // namespace mktree
