// mktree export STORE --level K -o OUT.ply|OUT.glb [--boxes]: the level-k colouring (docs/design.md §9) as
// coloured geometry, read from the store leaf by leaf (engine/viz/level_export.h).
// mktree export STORE --clashes PAIRS.jsonl -o OUT.ply|OUT.glb [--boxes]: the same with each object in the
// colour of its worst clash class (engine/viz/clash_render.h), for a look at the clashes in a 3D viewer.
#include <chrono>
#include <cstdio>
#include <optional>

#include "engine/viz/clash_pairs_file.h"
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
  std::string clashes;  // --clashes PAIRS.jsonl instead of --level
  bool has_level = false;
};

int RunExport(const ExportArgs& a) {
  if (a.has_level == !a.clashes.empty())
    return Fail("export writes either --level K or --clashes PAIRS.jsonl: give exactly one");
  if (a.level < 0) return Fail("--level must be >= 0, not " + std::to_string(a.level));
  std::vector<std::string> inputs = {a.store};
  if (!a.clashes.empty()) inputs.push_back(a.clashes);
  if (Status st = CheckOutputFile(a.output, inputs); !st.ok()) return Fail(st.message());
  auto format = ExportFormatFor(a.output);
  if (!format.ok()) return Fail(format.status().message());
  auto reader = StoreReader::Open(a.store);
  if (!reader.ok()) return Fail(reader.status().message());
  std::optional<ClashMarks> marks;
  if (!a.clashes.empty()) {
    auto m = ReadClashPairs(a.clashes, (*reader)->object_count());
    if (!m.ok()) return Fail(m.status().message());
    marks = std::move(*m);
  }
  const auto start = std::chrono::steady_clock::now();
  Progress progress(a.quiet);
  ExportOptions opts;
  opts.level = a.level;
  opts.format = *format;
  opts.boxes = a.boxes;
  opts.clashes = marks ? &*marks : nullptr;
  opts.progress = [&](uint64_t done, uint64_t total) { progress.Update("export leaves", done, total); };
  auto report = ExportLevel(**reader, a.output, opts);
  progress.Done();
  if (!report.ok()) return Fail(report.status().message());
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!a.quiet && marks) {
    const ExportReport& r = *report;
    auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
    std::printf(
        "exported %s: clashes of %s %s, %llu objects (hard %llu, touch %llu, clearance %llu, no clash %llu), "
        "%llu vertices, %llu triangles, %s in %.2f s, peak RSS %s\n",
        a.output.c_str(), a.clashes.c_str(), a.boxes ? "boxes" : "geometry", u(r.total_objects()),
        u(r.objects[int(ClashMark::kHard)]), u(r.objects[int(ClashMark::kTouch)]),
        u(r.objects[int(ClashMark::kClearance)]), u(r.objects[int(ClashMark::kNone)]), u(r.total_vertices()),
        u(r.total_triangles()), HumanBytes(r.bytes).c_str(), secs, HumanBytes(PeakRssBytes()).c_str());
  } else if (!a.quiet) {
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
  CLI::Option* level = AddNumberOption(cmd, "--level", &args->level,
                                       "k: colour each object by its group at its depth-k ancestor")
                           ->default_str("");
  cmd->add_option(
      "--clashes", args->clashes,
      "PAIRS.jsonl (the JSON lines of mktree clash): instead of --level, colour each object by its "
      "worst class: red hard, orange touch, yellow clearance, grey in no pair");
  cmd->add_option("-o,--output", args->output, "OUT.ply (binary, vertex colours) or OUT.glb (glTF 2.0)")
      ->required();
  cmd->add_flag("--boxes", args->boxes,
                "Each object's AABB (8 vertices, 12 triangles) instead of its geometry");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress and no summary");
  cmd->callback([run, args, level] {
    args->has_level = level->count() > 0;
    *run = [args] { return RunExport(*args); };
  });
}

}  // namespace mktree::tools
