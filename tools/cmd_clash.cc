// mktree clash STORE and mktree collide STORE --object MESH: one JSON line per clashing pair
// (docs/cli.md, docs/clash.md §4), and with --summary a last line of counts and statistics. --revision R
// answers a kept revision; clash --since R prints only the pairs that are new or resolved since R.
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
#include "mktree/changes.h"
#include "mktree/clash.h"
#include "mktree/database.h"
#include "tools/clash_lines.h"
#include "tools/clash_test_lines.h"
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
  uint64_t revision = 0;  // with has_revision
  bool has_revision = false;
  uint64_t since = 0;  // clash --since R, with has_since
  bool has_since = false;
  std::string tests, compare;                    // clash --tests FILE [--compare PREVIOUS.jsonl]
  std::string bcf, bcf_version = "2.1", report;  // [--bcf OUT.bcf [--bcf-version 3.0]] [--report OUT.html]
  uint64_t snapshots = 50;
  // collide
  std::string object, translate, rotate;
};

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

// Writes pair lines to stdout; with names (--names), each pair's names read through a second handle on
// the revision the pair belongs to. The first error reading a name stops the printing and is kept.
struct PairPrinter {
  std::unique_ptr<Database> names_db;
  Status name_status;
  bool write_failed = false;

  Status OpenNames(const std::string& store, const OpenOptions& options) {
    MKTREE_ASSIGN_OR_RETURN(names_db, OpenNamesHandle(store, options));
    return Status::Ok();
  }

  void Print(const ClashPair& p, const char* status = nullptr) {
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
      line = PairLine(p, &*na, p.b == kCollideObject ? nullptr : &*nb, status);
    } else {
      line = PairLine(p, nullptr, nullptr, status);
    }
    if (std::fwrite(line.data(), 1, line.size(), stdout) != line.size()) write_failed = true;
  }
};

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
  if (a.has_revision) oo.revision = a.revision;
  auto db = Database::Open(a.store, oo);
  if (!db.ok()) return Fail(db.status().message());
  OpenOptions then_options = oo;
  std::unique_ptr<Database> then_db;
  if (a.has_since) {
    then_options.revision = a.since;
    auto t = Database::Open(a.store, then_options);
    if (!t.ok()) return Fail(t.status().message());
    then_db = std::move(*t);
    if (then_db->revision() > (*db)->revision())
      return Fail(a.store + ": --since " + std::to_string(a.since) + " is newer than revision " +
                  std::to_string((*db)->revision()));
  }
  Progress progress(!a.progress);
  if (a.progress) o.progress = [&](uint64_t done, uint64_t total) { progress.Update("clash", done, total); };
  PairPrinter now_lines, then_lines;
  if (a.names) {
    if (Status st = now_lines.OpenNames(a.store, oo); !st.ok()) return Fail(st.message());
    if (then_db) {
      if (Status st = then_lines.OpenNames(a.store, then_options); !st.ok()) return Fail(st.message());
    }
  }
  ClashStats stats;
  uint64_t new_pairs = 0, resolved_pairs = 0;
  Status st;
  if (collide) {
    st = (*db)->Collide(
        object, transform, o, [&](const ClashPair& p) { now_lines.Print(p); }, &stats);
  } else if (then_db && then_db->revision() == (*db)->revision()) {
    st = Status::Ok();  // the same revision: no pair is new, none resolved
  } else if (then_db) {
    auto visit = [&](const ClashPair& p, ClashChange change) {
      if (change == ClashChange::kNew) {
        ++new_pairs;
        now_lines.Print(p, "new");
      } else {
        ++resolved_pairs;
        then_lines.Print(p, "resolved");  // names as they were: a removed object has none now
      }
    };
    st = ClashSince(**db, *then_db, o, visit, &stats);
  } else {
    st = (*db)->SelfClash(
        o, [&](const ClashPair& p) { now_lines.Print(p); }, &stats);
  }
  progress.Done();
  if (!st.ok()) return Fail(st.message());
  for (const PairPrinter* lines : {&now_lines, &then_lines})
    if (!lines->name_status.ok()) return Fail(lines->name_status.message());
  if (a.summary) {
    std::string line = SummaryLine(stats, PeakRssBytes());
    if (then_db)
      line.insert(1, "\"new\": " + std::to_string(new_pairs) +
                         ", \"resolved\": " + std::to_string(resolved_pairs) + ", ");
    std::fwrite(line.data(), 1, line.size(), stdout);
  }
  if (now_lines.write_failed || then_lines.write_failed || std::fflush(stdout) != 0)
    return Fail("cannot write to standard output");
  return 0;
}

// clash --tests: the options that a test file decides are refused, the rest passed on.
int RunTests(const ClashArgs& a, const CLI::App& cmd) {
  for (const char* o : {"--clearance", "--touch-tolerance", "--max-pairs", "--no-touch", "--exclude-group",
                        "--since", "--summary"})
    if (cmd.get_option(o)->count() > 0)
      return Fail(std::string(o) +
                  " does not go with --tests (the test file says it; each test has a summary line)");
  if (a.window_mib > (uint64_t{1} << 40)) return Fail("--window-mib: at most 2^40");
  ClashTestsArgs t;
  t.store = a.store;
  t.tests = a.tests;
  t.compare = a.compare;
  t.bcf = a.bcf;
  t.bcf_version = a.bcf_version;
  t.report = a.report;
  t.snapshots = a.snapshots;
  t.names = a.names;
  t.progress = a.progress;
  t.cache_pages = a.cache_pages;
  t.window_bytes = a.window_mib << 20;
  t.threads = a.threads;
  t.has_revision = a.has_revision;
  t.revision = a.revision;
  return RunClashTestsCommand(t);
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
  AddNumberOption(cmd, "--revision", &a->revision, "Clash this kept revision (default: the newest)");
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
  auto* since = AddNumberOption(cmd, "--since", &args->since,
                                "Only the pairs that changed since this kept revision: new ones and resolved "
                                "ones (\"status\")");
  cmd->add_option(
      "--tests", args->tests,
      "Clash-test file (JSON, docs/clash_workflow.md): run its tests, lines with test, key, group");
  cmd->add_option(
      "--compare", args->compare,
      "With --tests: a previous run's lines; label clashes new / active and list the resolved ones");
  cmd->add_option(
      "--bcf", args->bcf,
      "With --tests: write the groups as a BCF-XML archive (one topic per group, docs/clash_reports.md)");
  cmd->add_option("--bcf-version", args->bcf_version, "BCF-XML version of --bcf: 2.1 or 3.0")
      ->check(CLI::IsMember({"2.1", "3.0"}));
  cmd->add_option("--report", args->report,
                  "With --tests: write a self-contained HTML report of the groups (docs/clash_reports.md)");
  AddNumberOption(cmd, "--snapshots", &args->snapshots,
                  "With --bcf/--report: pictures of the N worst groups (default 50; 0: none)");
  cmd->callback([run, args, cmd, since] {
    args->has_revision = cmd->get_option("--revision")->count() > 0;
    args->has_since = since->count() > 0;
    if (!args->tests.empty()) {
      *run = [args, cmd] { return RunTests(*args, *cmd); };
      return;
    }
    *run = [args] {
      if (!args->compare.empty()) return Fail("--compare goes with --tests");
      if (!args->bcf.empty() || !args->report.empty()) return Fail("--bcf and --report go with --tests");
      return Run(*args, false);
    };
  });
}

void RegisterCollide(CLI::App& app, CommandRun* run) {
  auto args = std::make_shared<ClashArgs>();
  CLI::App* cmd =
      app.add_subcommand("collide", "One object (all meshes of a scene file) against a store: JSON lines");
  AddCommon(cmd, args.get());
  cmd->add_option("--object", args->object, "Scene file (any format the readers take)")->required();
  cmd->add_option("--translate", args->translate, "X,Y,Z: move the object by this");
  cmd->add_option("--rotate-deg", args->rotate, "AX,AY,AZ: rotate about x, then y, then z (degrees)");
  cmd->callback([run, args, cmd] {
    args->has_revision = cmd->get_option("--revision")->count() > 0;
    *run = [args] { return Run(*args, true); };
  });
}

}  // namespace mktree::tools
