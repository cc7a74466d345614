// mktree's public build API: write a store from scene files or from objects the caller hands over, with
// the options of `mktree build` (docs/cli.md), in bounded memory (docs/design.md §10).
//
//   mktree::BuildOptions opts;
//   opts.backend = mktree::BuildOptions::Backend::kPagedFile;
//   auto stats = mktree::BuildFromFiles({"ship.obj", "tanker:1000:7"}, "ship.mkt", opts);
//   if (!stats.ok()) { ... stats.status().ToString() names the file and line ... }
//
//   std::vector<mktree::SceneObject> objects = ...;   // vertices, triangles, name, attributes
//   auto built = mktree::BuildFromObjects(objects, "mine.mkt", opts);
//
// The store is written atomically: on any error (bad input, a full disk, a throwing callback) nothing of
// it is left behind and a store already at the path stays as it was. A second build of the same path at
// the same time fails at once (the writer lock, docs/cli.md).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "mktree/geometry.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

enum class BuildStage { kRead, kBuildTree, kWritePages, kWriteTable };
// "read", "build tree", "write pages", "write object table".
const char* BuildStageName(BuildStage stage);

// Called now and then during each stage, on the building thread; `total` is 0 when unknown (while the
// objects are read). An exception it throws ends the build with an Internal error.
using BuildProgress = std::function<void(BuildStage stage, uint64_t done, uint64_t total)>;

struct BuildOptions {
  enum class Backend { kHdf5, kPagedFile };  // docs/store_format.md
  enum class Codec { kZstd, kNone };         // how geometry is kept in leaf entries
  // How nodes are split (docs/design.md §3.5): kCompact (SOA over the axes the objects spread along),
  // kSoa (the reference SOA exactly), kSoaFill (SOA with page fill ranked first near the leaves).
  enum class SplitPolicy { kCompact, kSoa, kSoaFill };

  Backend backend = Backend::kHdf5;
  Codec codec = Codec::kZstd;
  int zstd_level = 3;            // zstd's minimum (negative: fast modes) to 22; 0: zstd's default
  uint32_t block_size = 4096;    // bytes, at least 512
  uint32_t blocks_per_page = 3;  // d: a leaf page is block_size x d bytes (at most 1 GiB)
  double balance_r = 0.3;        // SOA balance ratio, 0 <= r < 0.5
  uint32_t split_budget = 64;    // SplitTree nodes per internal node (0: no SplitTrees)
  SplitPolicy split_policy = SplitPolicy::kCompact;
  // Threads encoding objects and building the tree, the caller's included (0: one per hardware thread).
  // The store is the same for any number.
  unsigned threads = 0;
  // Where the temporary spill files go (empty: beside the store).
  std::string spill_dir;
  // STEP inputs are tessellated (docs/formats.md, STEP): the largest distance in metres between a face and
  // its triangles, and the largest angle in radians between adjacent triangles' normals. Both must be
  // finite and positive; other formats ignore them.
  double chord_tolerance = 0.0005;
  double angular_deflection = 0.5;
  BuildProgress progress;  // optional
  // 0: one store at the path. K >= 1: a sharded store (docs/shards.md): the path is its manifest, and K
  // ordinary stores "<path>.shard-<i>.mkt" with their id files "<path>.shard-<i>.ids" lie beside it.
  // Database::Open opens the manifest and answers as the store of the same scene would. The inputs are
  // read once for the sample and once per shard: BuildFromObjects over an ObjectSource refuses shards.
  uint32_t shards = 0;
};

struct BuildStats {
  uint64_t objects = 0;
  uint64_t triangles = 0;
  uint64_t leaves = 0;
  uint64_t pages = 0;
  uint64_t page_bytes = 0;          // block_size x blocks_per_page
  uint32_t height = 0;              // of the tree
  double mean_page_fill = 0;        // share of the leaf pages' bytes used, 0..1
  Vec3d origin;                     // the store frame's origin (docs/store_format.md); 0 for most scenes
  uint64_t raw_geometry_bytes = 0;  // Mesh::RawGeometryBytes summed
  uint64_t encoded_bytes = 0;       // leaf entries' bytes after the codec
  uint64_t store_bytes = 0;         // size of the finished file
  double read_seconds = 0, build_seconds = 0, write_seconds = 0, total_seconds = 0;
  // Remarks that did not stop the build, one line each (coarse boxes far from the origin, input read at
  // float32 precision): what `mktree build` prints as "warning: ...".
  std::vector<std::string> warnings;
};

// Builds the store at `store_path` from `inputs`, read in order (object ids continue across them): scene
// files of any format `mktree build` reads (.obj, .mks, STEP, glTF/GLB, PLY, STL, OFF, AC3D, ... through
// assimp) or "tanker:N" / "tanker:N:SEED" (the synthetic tanker, decimal N from 1 to 2^32, SEED default 1).
// Bad input is an error naming the file and line; an input that is missing or not a regular file, and a store
// path that names one of the inputs or something other than a regular file, are refused before anything is
// read. No input, or no object with geometry in them, is InvalidArgument.
Result<BuildStats> BuildFromFiles(const std::vector<std::string>& inputs, const std::string& store_path,
                                  const BuildOptions& options = {});

// The objects of a build from the caller, one a call: fills `*next` and returns true, or returns false
// at the end. A non-ok Status ends the build and is returned as it is. `next->id` is ignored: objects
// are numbered 0, 1, 2, ... in the order given. Each must have at least one triangle, indices below its
// vertex count, and finite coordinates of magnitude at most kMaxCoordinate (else InvalidArgument naming
// the object's number and name); `source` and `attributes` are the caller's to fill.
using ObjectSource = std::function<Result<bool>(SceneObject* next)>;

Result<BuildStats> BuildFromObjects(const ObjectSource& source, const std::string& store_path,
                                    const BuildOptions& options = {});
// The same over a vector (copied one object at a time as the build reads it).
Result<BuildStats> BuildFromObjects(const std::vector<SceneObject>& objects, const std::string& store_path,
                                    const BuildOptions& options = {});

}  // namespace mktree
