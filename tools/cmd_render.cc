// mktree render STORE --level K -o OUT.png [--view top|side|front] [--size WxH] [--overlay]: a picture of
// the level-k colouring (docs/design.md §9), drawn from the store leaf by leaf (engine/viz/level_render.h).
// mktree render STORE --clashes PAIRS.jsonl -o OUT.png [--focus K] [--view ...] [--size WxH]: the scene with
// the objects of the pairs `mktree clash` printed highlighted by class (engine/viz/clash_render.h).
#include <chrono>
#include <cstdio>

#include "engine/viz/clash_pairs_file.h"
#include "engine/viz/clash_render.h"
#include "engine/viz/level_render.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/path_checks.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

struct RenderArgs {
  std::string store, output;
  int level = 0;
  std::string view = "top";
  std::string size = "1600x400";
  bool overlay = false;
  bool quiet = false;
  std::string clashes;  // --clashes PAIRS.jsonl instead of --level
  uint64_t focus = 0;   // --focus K (from 1), with --clashes
  bool has_level = false;
};

Result<RenderView> ParseRenderView(const std::string& name) {
  if (name == "top") return RenderView::kTop;
  if (name == "side") return RenderView::kSide;
  if (name == "front") return RenderView::kFront;
  return Status::InvalidArgument("--view must be top, side or front, not '" + name + "'");
}

int RunClashRender(const RenderArgs& a, const StoreReader& store, RenderView view, unsigned w, unsigned h,
                   std::chrono::steady_clock::time_point start, Progress* progress) {
  auto marks = ReadClashPairs(a.clashes, store.object_count(), a.focus);
  if (!marks.ok()) return Fail(marks.status().message());
  ClashRenderOptions opts;
  opts.view = view;
  opts.width = w;
  opts.height = h;
  opts.focus = a.focus > 0;
  opts.progress = [&](uint64_t done, uint64_t total) { progress->Update("render leaves", done, total); };
  auto report = RenderClashes(store, *marks, a.output, opts);
  progress->Done();
  if (!report.ok()) return Fail(report.status().message());
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!a.quiet) {
    const ClashRenderReport& r = *report;
    const ClashMarks& m = *marks;
    auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
    std::printf(
        "rendered %s: %ux%u, %s view, %llu objects, %llu triangles, %.3g px per unit, in %.2f s, peak RSS "
        "%s\n",
        a.output.c_str(), w, h, a.view.c_str(), u(store.object_count()), u(r.triangles), r.pixels_per_metre,
        secs, HumanBytes(PeakRssBytes()).c_str());
    std::printf("clashes %s: %llu pairs (%llu other lines)\n", a.clashes.c_str(), u(m.pair_count()),
                u(m.other_lines));
    for (ClashMark c : {ClashMark::kHard, ClashMark::kTouch, ClashMark::kClearance}) {
      const int i = static_cast<int>(c);
      std::printf("  %-9s %12llu pairs %12llu objects\n", ClashMarkName(c), u(m.pairs[i]), u(r.objects[i]));
    }
    std::printf("  %-9s %12s       %12llu objects\n", "no clash", "", u(r.objects[0]));
    if (m.focus) {
      const Box3f& b = r.framed;
      std::printf(
          "focus: pair %llu (line %llu): objects %llu and %llu, %s; framed [%g, %g, %g] to [%g, %g, %g]\n",
          u(a.focus), u(m.focus->line), u(m.focus->a), u(m.focus->b), ClashMarkName(m.focus->cls), b.min[0],
          b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]);
    }
  }
  return 0;
}

int RunRender(const RenderArgs& a) {
  if (a.has_level == !a.clashes.empty())
    return Fail("render draws either --level K or --clashes PAIRS.jsonl: give exactly one");
  if (a.level < 0) return Fail("--level must be >= 0, not " + std::to_string(a.level));
  if (a.focus > 0 && a.clashes.empty()) return Fail("--focus goes with --clashes");
  if (a.overlay && !a.clashes.empty()) return Fail("--overlay goes with --level");
  auto view = ParseRenderView(a.view);
  if (!view.ok()) return Fail(view.status().message());
  const size_t x = a.size.find('x');
  const auto w = ParseUnsigned<unsigned>(std::string_view(a.size).substr(0, x));
  const auto h =
      x == std::string::npos ? std::nullopt : ParseUnsigned<unsigned>(std::string_view(a.size).substr(x + 1));
  if (!w || !h) return Fail("--size must be WIDTHxHEIGHT (e.g. 1600x400), not '" + a.size + "'");
  if (*w < 64 || *h < 64 || *w > 16384 || *h > 16384)
    return Fail("--size must be between 64x64 and 16384x16384");
  std::vector<std::string> inputs = {a.store};
  if (!a.clashes.empty()) inputs.push_back(a.clashes);
  if (Status st = CheckOutputFile(a.output, inputs); !st.ok()) return Fail(st.message());
  if (a.output.size() < 4 || a.output.compare(a.output.size() - 4, 4, ".png") != 0)
    return Fail(a.output + ": the picture is written as PNG; name it *.png");
  auto reader = StoreReader::Open(a.store);
  if (!reader.ok()) return Fail(reader.status().message());
  const auto start = std::chrono::steady_clock::now();
  Progress progress(a.quiet);
  if (!a.clashes.empty()) return RunClashRender(a, **reader, *view, *w, *h, start, &progress);
  RenderOptions opts;
  opts.level = a.level;
  opts.view = *view;
  opts.width = *w;
  opts.height = *h;
  opts.overlay = a.overlay;
  opts.progress = [&](uint64_t done, uint64_t total) { progress.Update("render leaves", done, total); };
  auto report = RenderLevel(**reader, a.output, opts);
  progress.Done();
  if (!report.ok()) return Fail(report.status().message());
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!a.quiet) {
    const RenderReport& r = *report;
    std::printf(
        "rendered %s: %ux%u, level %d, %s view, %llu objects (Sn1 %llu, Sn2 %llu, Sm %llu, above level "
        "%llu), "
        "%llu triangles, %.3g px per unit, in %.2f s, peak RSS %s\n",
        a.output.c_str(), *w, *h, a.level, a.view.c_str(),
        static_cast<unsigned long long>(r.objects[0] + r.objects[1] + r.objects[2] + r.objects[3]),
        static_cast<unsigned long long>(r.objects[0]), static_cast<unsigned long long>(r.objects[1]),
        static_cast<unsigned long long>(r.objects[2]), static_cast<unsigned long long>(r.objects[3]),
        static_cast<unsigned long long>(r.triangles), r.pixels_per_metre, secs,
        HumanBytes(PeakRssBytes()).c_str());
  }
  return 0;
}

}  // namespace

void RegisterRender(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<RenderArgs>();
  CLI::App* cmd = app.add_subcommand(
      "render",
      "Draw the level-k colouring as a PNG (blue Sn1, red Sn2, green overlap Sm, grey above level), or the "
      "clashes of a pairs file (--clashes)");
  cmd->add_option("store", args->store, "Store file")->required();
  CLI::Option* level = AddNumberOption(cmd, "--level", &args->level,
                                       "k: colour each object by its group at its depth-k ancestor")
                           ->default_str("");
  cmd->add_option(
      "--clashes", args->clashes,
      "PAIRS.jsonl (the JSON lines of mktree clash): instead of --level, draw the objects in a pair "
      "in red (hard), orange (touch) or yellow (clearance) through a faded grey scene");
  AddNumberOption(
      cmd, "--focus", &args->focus,
      "K: with --clashes, frame the view on the K-th pair of the file (from 1) and its two objects")
      ->default_str("");
  cmd->add_option("-o,--output", args->output, "OUT.png")->required();
  cmd->add_option("--view", args->view, "top (x right, y up), side (x right, z up) or front (y right, z up)")
      ->capture_default_str();
  cmd->add_option("--size", args->size, "WIDTHxHEIGHT in pixels (64..16384 each)")->capture_default_str();
  cmd->add_flag("--overlay", args->overlay,
                "Outline the nodes at depth k, their overlap slabs and SplitTree cells");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress and no summary");
  cmd->callback([run, args, level] {
    args->has_level = level->count() > 0;
    *run = [args] { return RunRender(*args); };
  });
}

}  // namespace mktree::tools
