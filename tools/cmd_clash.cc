// mktree clash STORE and mktree collide STORE --object MESH: one JSON line per clashing pair
// (docs/cli.md, docs/clash.md §4), and with --summary a last line of counts and statistics.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "engine/scene/scene_source.h"
#include "mktree/clash.h"
#include "mktree/database.h"
#include "tools/cli_numbers.h"
#include "tools/command.h"
#include "tools/json_text.h"
#include "tools/path_checks.h"
#include "tools/progress.h"

namespace mktree::tools {

namespace {

struct ClashArgs {
  std::string store;
  double clearance = 0;
  double touch_tolerance = 0.002;
  uint64_t cache_pages = 4096;
  uint64_t window_mib = 0;  // clash: 0 is kDefaultClashWindowBytes
  unsigned threads = 0;
  uint64_t max_pairs = std::numeric_limits<uint64_t>::max();
  std::string exclude_group;
  bool no_touch = false;
  bool summary = false;
  bool progress = false;
  bool names = false;
  // collide
  std::string object, translate, rotate;
};

void AppendReal(std::string* out, double v) {
  if (!std::isfinite(v)) {
    *out += "null";
    return;
  }
  // Shortest round-trip: the same double back, without printf's cost (which bounded a 2-thread clash).
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  out->append(buf, r.ptr);
}

void AppendPoint(std::string* out, const Vec3d& p) {
  *out += '[';
  for (int i = 0; i < 3; ++i) {
    if (i) *out += ", ";
    AppendReal(out, p[i]);
  }
  *out += ']';
}

const char* ClassName(ClashClass c) {
  switch (c) {
    case ClashClass::kHard:
      return "hard";
    case ClashClass::kTouch:
      return "touch";
    case ClashClass::kClearance:
      return "clearance";
  }
  return "hard";
}

const char* MeetingName(ClashMeeting m) {
  switch (m) {
    case ClashMeeting::kCross:
      return "cross";
    case ClashMeeting::kAInsideB:
      return "a_inside_b";
    case ClashMeeting::kBInsideA:
      return "b_inside_a";
    case ClashMeeting::kApart:
      return "apart";
    case ClashMeeting::kResolutionGap:
      return "resolution_gap";
  }
  return "cross";
}

// The JSON line of one pair; in collide, b (the query object) is -1. With names (--names), name_a and
// name_b follow b (name_b is null in collide).
std::string PairLine(const ClashPair& p, const std::string* name_a = nullptr,
                     const std::string* name_b = nullptr) {
  std::string s = "{\"a\": " + std::to_string(p.a) + ", \"b\": ";
  s += p.b == kCollideObject ? std::string("-1") : std::to_string(p.b);
  if (name_a) {
    s += ", \"name_a\": \"" + JsonText(*name_a) + "\", \"name_b\": ";
    s += name_b ? "\"" + JsonText(*name_b) + "\"" : std::string("null");
  }
  s += ", \"class\": \"";
  s += ClassName(p.cls);
  s += "\", \"distance\": ";
  AppendReal(&s, p.distance);
  s += ", \"depth_lower\": ";
  AppendReal(&s, p.depth_lower);
  s += ", \"depth_upper\": ";
  AppendReal(&s, p.depth_upper);
  s += ", \"depth_exact\": ";
  s += p.depth_exact ? "true" : "false";
  s += ", \"point_a\": ";
  AppendPoint(&s, p.point_a);
  s += ", \"point_b\": ";
  AppendPoint(&s, p.point_b);
  s += ", \"meeting\": \"";
  s += MeetingName(p.meeting);
  s += "\", \"resolution\": ";
  AppendReal(&s, p.resolution);
  s += "}\n";
  return s;
}

std::string SummaryLine(const ClashStats& s) {
  auto u = [](const char* k, uint64_t v) { return std::string("\"") + k + "\": " + std::to_string(v); };
  auto d = [](const char* k, double v) {
    std::string r = std::string("\"") + k + "\": ";
    AppendReal(&r, v);
    return r;
  };
  std::string line =
      "{" + u("pairs", s.hard + s.touch + s.clearance) + ", " + u("hard", s.hard) + ", " +
      u("touch", s.touch) + ", " + u("clearance", s.clearance) + ", " + u("pages_read", s.pages_read) + ", " +
      u("store_pages", s.store_pages) + ", " + d("seconds", s.total_seconds) + ", " +
      u("reported_pairs", s.reported_pairs) + ", " + u("capped_pairs", s.capped_pairs) + ", " +
      u("unreported_touches", s.unreported_touches) + ", " + u("pages_touched", s.pages_touched) + ", " +
      u("distinct_pages", s.distinct_pages) + ", " + u("leaf_reads", s.leaf_reads) + ", " +
      u("leaf_rereads", s.leaf_rereads) + ", " + u("window_peak_bytes", s.window_peak_bytes) + ", " +
      u("window_budget_bytes", s.window_budget_bytes) + ", " + u("leaf_pairs_tree", s.leaf_pairs_tree) +
      ", " + u("leaf_pairs_visited", s.leaf_pairs_visited) + ", " + u("candidate_pairs", s.candidate_pairs) +
      ", " + u("excluded_pairs", s.excluded_pairs) + ", " + u("bound_rejects", s.bound_rejects) + ", " +
      u("triangle_tests", s.triangle_tests) + ", " + u("containment_tests", s.containment_tests) + ", " +
      u("shapes_prepared", s.shapes_prepared) + ", " + u("hierarchies_built", s.hierarchies_built) + ", " +
      u("classifiers_built", s.classifiers_built) + ", " + d("broad_seconds", s.broad_seconds) + ", " +
      d("read_seconds", s.read_seconds) + ", " + d("narrow_seconds", s.narrow_seconds) + ", " +
      u("peak_rss_bytes", PeakRssBytes()) + "}\n";
  return line;
}

// "X,Y,Z" as three finite numbers.
std::optional<Vec3d> ParseTriple(const std::string& text) {
  Vec3d v;
  size_t at = 0;
  for (int i = 0; i < 3; ++i) {
    const size_t comma = i < 2 ? text.find(',', at) : text.size();
    if (comma == std::string::npos) return std::nullopt;
    auto d = ParseReal(std::string_view(text).substr(at, comma - at));
    if (!d || !std::isfinite(*d)) return std::nullopt;
    v[i] = *d;
    at = comma + 1;
  }
  return v;
}

// Every object of the scene file, as one mesh.
Result<Mesh> ReadObjectFile(const std::string& path) {
  MKTREE_RETURN_IF_ERROR(CheckInputFile(path));
  MKTREE_ASSIGN_OR_RETURN(auto source, OpenSceneFile(path));
  Mesh all;
  SceneObject obj;
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, source->Next(&obj));
    if (!more) break;
    const uint32_t base = static_cast<uint32_t>(all.vertex_count());
    all.vertices.insert(all.vertices.end(), obj.mesh.vertices.begin(), obj.mesh.vertices.end());
    for (uint32_t t : obj.mesh.triangles) all.triangles.push_back(base + t);
  }
  if (all.triangles.empty()) return Status::InvalidArgument(path + ": no triangles");
  return all;
}

int Run(const ClashArgs& a, bool collide) {
#if defined(__GLIBC__)
  // One malloc arena for every thread, set before the worker threads start: a second arena holds its own
  // peak of the decoded leaves (a few MiB on the 100k tanker). It changes where blocks come from, not
  // what the program does; the cost is the arena's lock, taken by the threads' allocations. Here in the
  // tool, not the library: an embedding program keeps its own malloc settings.
  mallopt(M_ARENA_MAX, 1);
#endif
  ClashOptions o;
  o.clearance = a.clearance;
  o.touch_tolerance = a.touch_tolerance;
  o.report_touch = !a.no_touch;
  o.max_pairs = a.max_pairs;
  o.threads = a.threads;
  o.exclude_group_separator = a.exclude_group;
  if (a.window_mib > (uint64_t{1} << 40)) return Fail("--window-mib: at most 2^40");
  o.window_bytes = a.window_mib << 20;
  std::optional<RigidTransform> transform;
  Mesh object;
  if (collide) {
    Vec3d t, r;
    if (!a.translate.empty()) {
      auto v = ParseTriple(a.translate);
      if (!v) return Fail("--translate: '" + a.translate + "' is not X,Y,Z (three finite numbers)");
      t = *v;
    }
    if (!a.rotate.empty()) {
      auto v = ParseTriple(a.rotate);
      if (!v) return Fail("--rotate-deg: '" + a.rotate + "' is not AX,AY,AZ (three finite numbers)");
      r = *v;
    }
    if (!a.translate.empty() || !a.rotate.empty())
      transform = RigidTransform::FromEulerDegrees(r.x, r.y, r.z, t);
    auto m = ReadObjectFile(a.object);
    if (!m.ok()) return Fail(m.status().message());
    object = std::move(*m);
  }
  OpenOptions oo;
  oo.cache_pages = a.cache_pages;
  auto db = Database::Open(a.store, oo);
  if (!db.ok()) return Fail(db.status().message());
  Progress progress(!a.progress);
  if (a.progress) o.progress = [&](uint64_t done, uint64_t total) { progress.Update("clash", done, total); };
  std::unique_ptr<Database> names_db;
  if (a.names) {
    auto n = OpenNamesHandle(a.store, oo);
    if (!n.ok()) return Fail(n.status().message());
    names_db = std::move(*n);
  }
  bool write_failed = false;
  Status name_status;
  auto visit = [&](const ClashPair& p) {
    std::string line;
    if (names_db) {
      if (!name_status.ok()) return;
      auto na = names_db->ObjectName(p.a);
      Result<std::string> nb = std::string();
      if (p.b != kCollideObject) nb = names_db->ObjectName(p.b);
      if (!na.ok() || !nb.ok()) {
        name_status = na.ok() ? nb.status() : na.status();
        return;
      }
      line = PairLine(p, &*na, p.b == kCollideObject ? nullptr : &*nb);
    } else {
      line = PairLine(p);
    }
    if (std::fwrite(line.data(), 1, line.size(), stdout) != line.size()) write_failed = true;
  };
  ClashStats stats;
  const Status st =
      collide ? (*db)->Collide(object, transform, o, visit, &stats) : (*db)->SelfClash(o, visit, &stats);
  progress.Done();
  if (!st.ok()) return Fail(st.message());
  if (!name_status.ok()) return Fail(name_status.message());
  if (a.summary) {
    const std::string line = SummaryLine(stats);
    std::fwrite(line.data(), 1, line.size(), stdout);
  }
  if (write_failed || std::fflush(stdout) != 0) return Fail("cannot write to standard output");
  return 0;
}

void AddCommon(CLI::App* cmd, ClashArgs* a) {
  cmd->add_option("store", a->store, "Store file")->required();
  AddNumberOption(cmd, "--clearance", &a->clearance, "Clearance C: pairs closer than C are reported");
  AddNumberOption(cmd, "--touch-tolerance", &a->touch_tolerance,
                  "Touch tolerance T: meeting pairs with depth <= T are touches");
  AddNumberOption(cmd, "--cache-pages", &a->cache_pages, "Page cache, in pages");
  AddNumberOption(cmd, "--threads", &a->threads, "Worker threads (0: one per core); output is the same");
  AddNumberOption(cmd, "--max-pairs", &a->max_pairs, "Report at most N pairs (the rest are counted)");
  cmd->add_flag("--no-touch", a->no_touch, "Count touch pairs without printing them");
  cmd->add_flag("--summary", a->summary, "A last line with counts and statistics");
  cmd->add_flag("--progress", a->progress, "Progress on standard error");
  cmd->add_flag("--names", a->names,
                "Each pair's object names as name_a, name_b (null for collide's object)");
}

}  // namespace

void RegisterClash(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<ClashArgs>();
  CLI::App* cmd = app.add_subcommand("clash", "Self-clash of a store: one JSON line per clashing pair");
  AddCommon(cmd, args.get());
  cmd->add_option("--exclude-group", args->exclude_group,
                  "Skip pairs whose names agree up to this separator (e.g. /)");
  AddNumberOption(cmd, "--window-mib", &args->window_mib,
                  "Memory for decoded leaves kept between their pairs, in MiB (0: the default, 32)");
  cmd->callback([run, args] { *run = [args] { return Run(*args, false); }; });
}

void RegisterCollide(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<ClashArgs>();
  CLI::App* cmd =
      app.add_subcommand("collide", "One object (all meshes of a scene file) against a store: JSON lines");
  AddCommon(cmd, args.get());
  cmd->add_option("--object", args->object, "Scene file (any format the readers take)")->required();
  cmd->add_option("--translate", args->translate, "X,Y,Z: move the object by this");
  cmd->add_option("--rotate-deg", args->rotate, "AX,AY,AZ: rotate about x, then y, then z (degrees)");
  cmd->callback([run, args] { *run = [args] { return Run(*args, true); }; });
}

}  // namespace mktree::tools
