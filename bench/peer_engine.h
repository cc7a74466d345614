// The interface every engine of peers_bench implements (mktree's variants, libspatialindex, SQLite R*Tree,
// Boost.Geometry), so that the driver builds, opens and queries them all the same way.
//
// Protocol, per engine: Build() runs in a child process of its own (so its peak RSS is its own); the
// parent then Open()s the files cold (the smallest sensible cache, OS cache bypassed or dropped before each
// query), runs every query with ClearCache() before each, Close()s, re-Open()s warm (a cache of
// kWarmCacheBytes, OS cache left alone) and runs every query twice. Answers are AABB answers only.
//
// Thread safety: none; the driver uses one engine from one thread.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "engine/scene/scene_source.h"
#include "engine/store_format/object_codec.h"
#include "mktree/database.h"
#include "mktree/status.h"

namespace mktree::bench {

// Page size of every paged engine (mktree's MemPage default; libspatialindex's disk storage manager).
inline constexpr uint32_t kPageBytes = 12288;
// SQLite page sizes are powers of two (512..65536); neither neighbour of 12 KiB is closer, and 16 KiB is
// the one that holds at least as much as a 12 KiB page (so SQLite is not charged extra pages).
inline constexpr uint32_t kSqlitePageBytes = 16384;
// Cache budget of the warm phase, the same bytes for every engine (pages = bytes / page size).
inline constexpr uint64_t kWarmCacheBytes = 64ull << 20;
// Cache of the cold phase for engines that cache within a query (mktree, SQLite): emptied before each
// query, so it only saves re-reading a page touched twice by the same query.
inline constexpr uint64_t kColdCacheBytes = 48ull << 20;

// What a query cost in I/O. `pages` are page reads from the engine's file (disk accesses); `inner_pages`
// is the part of them spent on internal (non-leaf) nodes where the engine can tell (libspatialindex).
struct Io {
  uint64_t pages = 0;
  uint64_t inner_pages = 0;
  uint64_t bytes = 0;
};

// Key/value facts a build reports back to the parent (through a pipe, as text).
using Facts = std::map<std::string, double>;

// A scene to build from: "tanker:N:SEED" or a file path (read with OpenSceneFile).
struct SceneSpec {
  std::string spec;
  Result<std::unique_ptr<SceneSource>> Open(ObjectId first_id = 0) const;
};

// The per-object geometry every paged engine stores: mktree's own leaf entry (object_codec.h), encoded
// the way ingest encodes it (same codec options, same shape flags), so all leaves carry the same bytes.
void EncodePeerEntry(const SceneObject& obj, const CodecOptions& codec, std::vector<uint8_t>* out);

class Engine {
 public:
  virtual ~Engine() = default;
  virtual std::string name() const = 0;
  // Files that hold the engine's data (sized for the report, dropped from the OS cache, removed at the end).
  virtual std::vector<std::string> files() const = 0;
  // How cold reads avoid the OS page cache, for the report.
  virtual std::string cold_method() const = 0;

  // Builds the engine's files from the scene. Runs in a child process. `facts` gets what Open needs later
  // and what the report shows (e.g. objects per leaf page).
  virtual Status Build(const SceneSpec& scene, Facts* facts) = 0;
  virtual Status Open(bool warm, const Facts& build_facts) = 0;
  virtual void Close() = 0;
  // Empties the engine's own cache (not the OS's).
  virtual void ClearCache() = 0;
  // AABB query: `hits` gets the sorted ids; `io` the query's I/O.
  virtual Status Run(const Query& q, std::vector<ObjectId>* hits, Io* io) = 0;
  // B of the I/O floor ceil(T / B): mean objects per leaf page (0 when the engine has no pages).
  virtual double objects_per_page(const Facts& build_facts) const = 0;
};

std::unique_ptr<Engine> MakeSpatialIndexEngine(const std::string& dir, const CodecOptions& codec,
                                               uint32_t leaf_capacity, uint32_t index_capacity);
std::unique_ptr<Engine> MakeSqliteEngine(const std::string& dir, const CodecOptions& codec);

}  // namespace mktree::bench
