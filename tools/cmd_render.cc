// mktree render STORE --level K -o OUT.png [--view top|side|front] [--size WxH] [--overlay]: a picture of
// the level-k colouring (docs/design.md §9), drawn from the store leaf by leaf (engine/viz/level_render.h).
#include <chrono>
#include <cstdio>

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
};

Result<RenderView> ParseRenderView(const std::string& name) {
  if (name == "top") return RenderView::kTop;
  if (name == "side") return RenderView::kSide;
  if (name == "front") return RenderView::kFront;
  return Status::InvalidArgument("--view must be top, side or front, not '" + name + "'");
}

int RunRender(const RenderArgs& a) {
  if (a.level < 0) return Fail("--level must be >= 0, not " + std::to_string(a.level));
  auto view = ParseRenderView(a.view);
  if (!view.ok()) return Fail(view.status().message());
  const size_t x = a.size.find('x');
  const auto w = ParseUnsigned<unsigned>(std::string_view(a.size).substr(0, x));
  const auto h =
      x == std::string::npos ? std::nullopt : ParseUnsigned<unsigned>(std::string_view(a.size).substr(x + 1));
  if (!w || !h) return Fail("--size must be WIDTHxHEIGHT (e.g. 1600x400), not '" + a.size + "'");
  if (*w < 64 || *h < 64 || *w > 16384 || *h > 16384)
    return Fail("--size must be between 64x64 and 16384x16384");
  if (Status st = CheckOutputFile(a.output, {a.store}); !st.ok()) return Fail(st.message());
  if (a.output.size() < 4 || a.output.compare(a.output.size() - 4, 4, ".png") != 0)
    return Fail(a.output + ": the picture is written as PNG; name it *.png");
  auto reader = StoreReader::Open(a.store);
  if (!reader.ok()) return Fail(reader.status().message());
  const auto start = std::chrono::steady_clock::now();
  Progress progress(a.quiet);
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
      "Draw the level-k colouring as a PNG (blue Sn1, red Sn2, green overlap Sm, grey above level)");
  cmd->add_option("store", args->store, "Store file")->required();
  AddNumberOption(cmd, "--level", &args->level, "k: colour each object by its group at its depth-k ancestor")
      ->required()
      ->default_str("");
  cmd->add_option("-o,--output", args->output, "OUT.png")->required();
  cmd->add_option("--view", args->view, "top (x right, y up), side (x right, z up) or front (y right, z up)")
      ->capture_default_str();
  cmd->add_option("--size", args->size, "WIDTHxHEIGHT in pixels (64..16384 each)")->capture_default_str();
  cmd->add_flag("--overlay", args->overlay,
                "Outline the nodes at depth k, their overlap slabs and SplitTree cells");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress and no summary");
  cmd->callback([run, args] { *run = [args] { return RunRender(*args); }; });
}

}  // namespace mktree::tools
