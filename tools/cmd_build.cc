// mktree build SCENE... -o STORE: ingest scenes and write a store (docs/cli.md).
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "mktree/build.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/path_checks.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

struct BuildArgs {
  std::vector<std::string> inputs;
  std::string output;
  std::string backend = "hdf5";
  std::string codec = "zstd";
  int zstd_level = BuildOptions{}.zstd_level;
  uint32_t block_size = 4096;
  uint32_t blocks_per_page = 3;
  double r = 0.3;
  uint32_t split_budget = 64;
  std::string split_policy = "compact";
  uint32_t shards = 0;
  std::string spill_dir;
  double chord_tolerance = BuildOptions{}.chord_tolerance;
  double angular_deflection = BuildOptions{}.angular_deflection;
  bool quiet = false;
};

int RunBuild(const BuildArgs& a) {
  // The options are checked here first so that errors name the flags; BuildFromFiles checks them again.
  BuildOptions opts;
  if (a.backend == "hdf5")
    opts.backend = BuildOptions::Backend::kHdf5;
  else if (a.backend == "pagefile")
    opts.backend = BuildOptions::Backend::kPagedFile;
  else
    return Fail("--backend must be hdf5 or pagefile, not '" + a.backend + "'");
  if (a.codec == "zstd")
    opts.codec = BuildOptions::Codec::kZstd;
  else if (a.codec == "none")
    opts.codec = BuildOptions::Codec::kNone;
  else
    return Fail("--codec must be zstd or none, not '" + a.codec + "'");
  if (a.zstd_level < ZSTD_minCLevel() || a.zstd_level > ZSTD_maxCLevel())
    return Fail("--zstd-level must be from " + std::to_string(ZSTD_minCLevel()) + " to " +
                std::to_string(ZSTD_maxCLevel()) + ", not " + std::to_string(a.zstd_level));
  opts.zstd_level = a.zstd_level;
  opts.block_size = a.block_size;
  opts.blocks_per_page = a.blocks_per_page;
  opts.balance_r = a.r;
  opts.split_budget = a.split_budget;
  if (a.shards > 65536) return Fail("--shards must be from 1 to 65536");
  opts.shards = a.shards;
  if (!(a.r >= 0 && a.r < 0.5)) return Fail("--r must be in [0, 0.5)");
  if (!(std::isfinite(a.chord_tolerance) && a.chord_tolerance > 0))
    return Fail("--chord-tolerance must be a positive number of metres");
  if (!(std::isfinite(a.angular_deflection) && a.angular_deflection > 0))
    return Fail("--angular-deflection must be a positive number of radians");
  opts.chord_tolerance = a.chord_tolerance;
  opts.angular_deflection = a.angular_deflection;
  if (a.split_policy == "compact")
    opts.split_policy = BuildOptions::SplitPolicy::kCompact;
  else if (a.split_policy == "soa")
    opts.split_policy = BuildOptions::SplitPolicy::kSoa;
  else if (a.split_policy == "soa-fill")
    opts.split_policy = BuildOptions::SplitPolicy::kSoaFill;
  else
    return Fail("--split-policy must be compact, soa or soa-fill, not '" + a.split_policy + "'");
  if (a.block_size < 512 || a.blocks_per_page == 0 ||
      uint64_t{a.block_size} * a.blocks_per_page > (uint64_t{1} << 30))
    return Fail(
        "--block-size must be at least 512, --blocks-per-page at least 1, and the page (block size x "
        "blocks per page) at most 1 GiB");

  // Files are checked here too, for the command line's wording of what a path is (a FIFO, a directory).
  std::vector<std::string> files;
  for (const std::string& in : a.inputs) {
    if (in.rfind("tanker:", 0) == 0) continue;  // the generator: BuildFromFiles checks its spec
    if (Status st = CheckInputFile(in); !st.ok()) return Fail(st.message());
    files.push_back(in);
  }
  if (Status st = CheckOutputFile(a.output, files); !st.ok()) return Fail(st.message());
  if (!a.spill_dir.empty()) {
    std::error_code ec;
    if (!std::filesystem::is_directory(a.spill_dir, ec))
      return Fail("--spill-dir " + a.spill_dir + ": not a directory");
    opts.spill_dir = a.spill_dir;
  }
  Progress progress(a.quiet);
  opts.progress = [&](BuildStage s, uint64_t done, uint64_t total) {
    progress.Update(BuildStageName(s), done, total);
  };
  auto report = BuildFromFiles(a.inputs, a.output, opts);
  progress.Done();
  if (!report.ok()) return Fail(report.status().message());
  const BuildStats& r = *report;
  for (const std::string& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (!a.quiet) {
    std::printf("built %s: %llu objects, %llu triangles, %llu leaves, %llu pages of %llu B, height %u\n",
                a.output.c_str(), static_cast<unsigned long long>(r.objects),
                static_cast<unsigned long long>(r.triangles), static_cast<unsigned long long>(r.leaves),
                static_cast<unsigned long long>(r.pages), static_cast<unsigned long long>(r.page_bytes),
                r.height);
    if (r.origin.x != 0 || r.origin.y != 0 || r.origin.z != 0)
      std::printf("store frame: origin (%.17g, %.17g, %.17g); boxes are kept relative to it\n", r.origin.x,
                  r.origin.y, r.origin.z);
    std::printf(
        "store %s (raw geometry %s, encoded %s, ratio %.2f), page fill %.1f%%\n",
        HumanBytes(r.store_bytes).c_str(), HumanBytes(r.raw_geometry_bytes).c_str(),
        HumanBytes(r.encoded_bytes).c_str(),
        r.store_bytes ? static_cast<double>(r.raw_geometry_bytes) / static_cast<double>(r.store_bytes) : 0.0,
        100.0 * r.mean_page_fill);
    std::printf("time %.2fs (read %.2fs, tree %.2fs, write %.2fs), %.0f objects/s, peak RSS %s\n",
                r.total_seconds, r.read_seconds, r.build_seconds, r.write_seconds,
                static_cast<double>(r.objects) / std::max(r.total_seconds, 1e-9),
                HumanBytes(PeakRssBytes()).c_str());
  }
  return 0;
}

}  // namespace

void RegisterBuild(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<BuildArgs>();
  CLI::App* cmd = app.add_subcommand("build", "Ingest scenes and build an MKtree store");
  cmd->add_option(
         "scenes", args->inputs,
         "Scene files (.obj streamed; .mks; .step/.stp via OpenCASCADE; glTF/GLB/PLY/STL/OFF/AC3D/... via "
         "assimp) or tanker:N[:SEED]")
      ->required();
  cmd->add_option("-o,--output", args->output, "Store file to write (replaced atomically)")->required();
  cmd->add_option("--backend", args->backend, "hdf5 or pagefile")->capture_default_str();
  cmd->add_option("--codec", args->codec, "Page codec: zstd or none")->capture_default_str();
  AddNumberOption(cmd, "--zstd-level", &args->zstd_level, "zstd compression level");
  AddNumberOption(cmd, "--block-size", &args->block_size, "Disk block size in bytes");
  AddNumberOption(cmd, "--blocks-per-page", &args->blocks_per_page, "d: blocks per leaf page");
  AddNumberOption(cmd, "--r", &args->r, "SOA balance ratio, 0 <= r < 0.5");
  AddNumberOption(cmd, "--split-budget", &args->split_budget,
                  "SplitTree node budget per internal node (0: none)");
  cmd->add_option(
         "--split-policy", args->split_policy,
         "How nodes are split: compact (SOA over compact candidates), soa (docs/design.md §3.5, exactly) or "
         "soa-fill (SOA, page fill first near the leaves)")
      ->capture_default_str();
  AddNumberOption(cmd, "--shards", &args->shards,
                  "Build a sharded store of K shards (docs/shards.md): -o names its manifest; 0: one store");
  cmd->add_option(
      "--spill-dir", args->spill_dir,
      "Folder for the build's temporary files (the scene's geometry and records, the tree's lists, "
      "the OBJ reader's older vertices; unnamed, gone when the build ends); default: the store's folder");
  AddNumberOption(cmd, "--chord-tolerance", &args->chord_tolerance,
                  "STEP tessellation: largest distance in metres between a face and its triangles");
  AddNumberOption(cmd, "--angular-deflection", &args->angular_deflection,
                  "STEP tessellation: largest angle in radians between adjacent triangles' normals");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress and no summary");
  cmd->callback([run, args] { *run = [args] { return RunBuild(*args); }; });
}

}  // namespace mktree::tools
