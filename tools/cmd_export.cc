// mktree export STORE --level K -o OUT.ply|OUT.glb [--boxes]: the level-k colouring (docs/design.md §9) as
// coloured geometry, read from the store leaf by leaf (engine/viz/level_export.h).
#include <chrono>
#include <cstdio>

#include "engine/viz/level_export.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/path_checks.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

struct ExportArgs {
  std::string store, output;
  int level = 0;
  bool boxes = false;
  bool quiet = false;
};

int RunExport(const ExportArgs& a) {
  if (a.level < 0) return Fail("--level must be >= 0, not " + std::to_string(a.level));
  if (Status st = CheckOutputFile(a.output, {a.store}); !st.ok()) return Fail(st.message());
  auto format = ExportFormatFor(a.output);
  if (!format.ok()) return Fail(format.status().message());
  auto reader = StoreReader::Open(a.store);
  if (!reader.ok()) return Fail(reader.status().message());
  const auto start = std::chrono::steady_clock::now();
  Progress progress(a.quiet);
  ExportOptions opts;
  opts.level = a.level;
  opts.format = *format;
  opts.boxes = a.boxes;
  opts.progress = [&](uint64_t done, uint64_t total) { progress.Update("export leaves", done, total); };
  auto report = ExportLevel(**reader, a.output, opts);
  progress.Done();
  if (!report.ok()) return Fail(report.status().message());
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!a.quiet) {
    const ExportReport& r = *report;
    std::printf(
        "exported %s: level %d %s, %llu objects (Sn1 %llu, Sn2 %llu, Sm %llu, above level %llu), %llu "
        "vertices, "
        "%llu triangles, %s in %.2f s, peak RSS %s\n",
        a.output.c_str(), a.level, a.boxes ? "boxes" : "geometry",
        static_cast<unsigned long long>(r.total_objects()), static_cast<unsigned long long>(r.objects[0]),
        static_cast<unsigned long long>(r.objects[1]), static_cast<unsigned long long>(r.objects[2]),
        static_cast<unsigned long long>(r.objects[3]), static_cast<unsigned long long>(r.total_vertices()),
        static_cast<unsigned long long>(r.total_triangles()), HumanBytes(r.bytes).c_str(), secs,
        HumanBytes(PeakRssBytes()).c_str());
  }
  return 0;
}

}  // namespace

void RegisterExport(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<ExportArgs>();
  CLI::App* cmd = app.add_subcommand(
      "export",
      "Write the level-k colouring as PLY or GLB (blue Sn1, red Sn2, green overlap Sm, grey above level)");
  cmd->add_option("store", args->store, "Store file")->required();
  AddNumberOption(cmd, "--level", &args->level, "k: colour each object by its group at its depth-k ancestor")
      ->required()
      ->default_str("");
  cmd->add_option("-o,--output", args->output, "OUT.ply (binary, vertex colours) or OUT.glb (glTF 2.0)")
      ->required();
  cmd->add_flag("--boxes", args->boxes,
                "Each object's AABB (8 vertices, 12 triangles) instead of its geometry");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress and no summary");
  cmd->callback([run, args] { *run = [args] { return RunExport(*args); }; });
}

}  // namespace mktree::tools
