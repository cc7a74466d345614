// report_bench: the BCF archive and HTML report of a synthetic clash run (bench/README.md, "Clash
// reports"). One output per process, so that the peak RSS printed is that output's:
//   report_bench bcf|html [--clashes N] [--groups G] [--store STORE --snapshots S] [--out PATH]
// The run: N clashes in G groups of N/G members, objects with names, IFC types and GlobalIds; with a
// store, the members' objects are objects of the store (ids taken in turn) and the first S groups get a
// snapshot rendered from it.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include "engine/report/bcf_writer.h"
#include "engine/report/group_snapshot.h"
#include "engine/report/html_report.h"
#include "engine/viz/clash_render.h"

namespace {

using namespace mktree;

double PeakRssMiB() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;
}

std::string IfcGuid(uint64_t i) {
  static constexpr char k[] = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_$";
  std::string s(22, '0');
  for (int c = 21; c >= 0; --c, i /= 64) s[c] = k[i % 64];
  return s;
}

ObjectIdentity Object(uint64_t id, uint64_t n) {
  ObjectIdentity o;
  o.id = id;
  o.name = "Object " + std::to_string(n) + " <of the run>";
  o.source = "model.ifc";
  o.ifc_type = n % 3 == 0 ? "IfcBeam" : "IfcDuctSegment";
  o.global_id = IfcGuid(n * 7919 + 13);
  o.stable = o.source + "|" + o.global_id;
  return o;
}

ClashRun SyntheticRun(uint64_t clashes, uint64_t groups, const StoreReader* store) {
  ClashRun run;
  run.store = store ? store->path() : "synthetic.mkt";
  ClashTestSummary summary;
  summary.name = "mep-vs-structure";
  summary.mode = "clearance";
  summary.clearance = 0.05;
  summary.touch_tolerance = 0.002;
  summary.selected_a = 1000;
  summary.selected_b = 5000;
  summary.excluded_by_rule = {{"hosted_filling", 123}};
  run.tests.push_back(std::move(summary));
  const uint64_t objects = store ? store->object_count() : UINT64_MAX;
  uint64_t next = 0;
  for (uint64_t g = 0; g < groups; ++g) {
    ClashGroup group;
    group.test = "mep-vs-structure";
    const auto anchor = std::make_shared<const ObjectIdentity>(Object(next % objects, next));
    const ObjectIdentity first = Object((next + 1) % objects, next + 1);
    ++next;
    group.key = group.test + "|" + anchor->stable;
    const uint64_t members = clashes / groups + (g < clashes % groups ? 1 : 0);
    group.title = anchor->ifc_type + " " + anchor->name + " hit by " + std::to_string(members);
    for (uint64_t m = 0; m < members; ++m) {
      ClashRecord r;
      r.a = anchor;
      r.b = std::make_shared<const ObjectIdentity>(Object(next % objects, next));
      ++next;
      r.key = group.key + "|" + r.b->stable;
      r.pair.a = r.a->id, r.pair.b = r.b->id;
      r.pair.cls = m % 3 == 0 ? ClashClass::kHard : m % 3 == 1 ? ClashClass::kTouch : ClashClass::kClearance;
      r.pair.distance = r.pair.cls == ClashClass::kClearance ? 0.01 : -0.001 * (m % 50);
      r.pair.depth_upper = r.pair.depth_lower = std::max(0.0, -r.pair.distance);
      r.status = m % 2 ? ClashStatus::kActive : ClashStatus::kNew;
      group.members.push_back(std::move(r));
    }
    group.worst = ClashClass::kHard;
    group.worst_distance = -0.049;
    group.status = ClashStatus::kNew;
    // The box: with a store, the anchor's and the first member's stored boxes (world); else a fixed one.
    group.box.min = {double(g), 0, 0};
    group.box.max = {double(g) + 1, 1, 3};
    if (store) {
      group.box = Box3d{};
      for (uint64_t id : {anchor->id, first.id}) {
        auto b = StoredObjectBox(*store, id);
        if (!b.ok()) continue;
        for (int k = 0; k < 3; ++k) {
          group.box.min[k] = std::min(group.box.min[k], double(b->min[k]) + store->tree().origin[k]);
          group.box.max[k] = std::max(group.box.max[k], double(b->max[k]) + store->tree().origin[k]);
        }
      }
    }
    run.groups.push_back(std::move(group));
  }
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || (std::strcmp(argv[1], "bcf") && std::strcmp(argv[1], "html"))) {
    std::fprintf(
        stderr,
        "usage: report_bench bcf|html [--clashes N] [--groups G] [--store S --snapshots K] [--out P]\n");
    return 2;
  }
  const bool bcf = std::strcmp(argv[1], "bcf") == 0;
  uint64_t clashes = 100000, groups = 2000, snapshots = 0;
  std::string store_path, out = bcf ? "/tmp/report_bench.bcf" : "/tmp/report_bench.html";
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--clashes")
      clashes = std::stoull(v);
    else if (k == "--groups")
      groups = std::stoull(v);
    else if (k == "--snapshots")
      snapshots = std::stoull(v);
    else if (k == "--store")
      store_path = v;
    else if (k == "--out")
      out = v;
  }
  std::unique_ptr<StoreReader> store;
  if (!store_path.empty()) {
    auto r = StoreReader::Open(store_path);
    if (!r.ok()) return std::fprintf(stderr, "%s\n", r.status().ToString().c_str()), 1;
    store = std::move(*r);
  }
  const double rss_start = PeakRssMiB();
  auto t0 = std::chrono::steady_clock::now();
  const ClashRun run = SyntheticRun(clashes, groups, store.get());
  auto t1 = std::chrono::steady_clock::now();
  const double rss_run = PeakRssMiB();
  GroupSnapshotSource source;
  if (store && snapshots) source = StoreSnapshotSource(*store);
  uint64_t bytes = 0;
  if (bcf) {
    BcfOptions o;
    o.creation_time = 1767225600;
    o.snapshot = source;
    o.max_snapshots = snapshots;
    auto w = WriteBcf(run, out, o);
    if (!w.ok()) return std::fprintf(stderr, "%s\n", w.status().ToString().c_str()), 1;
    bytes = w->bytes;
  } else {
    HtmlReportOptions o;
    o.snapshot = source;
    o.max_snapshots = snapshots;
    auto w = WriteHtmlReport(run, out, o);
    if (!w.ok()) return std::fprintf(stderr, "%s\n", w.status().ToString().c_str()), 1;
    bytes = w->bytes;
  }
  auto t2 = std::chrono::steady_clock::now();
  std::printf(
      "%s: %llu clashes in %llu groups, %llu snapshots: run built in %.2f s (RSS %.1f -> %.1f MiB); "
      "written in %.2f s, %.1f MiB, peak RSS %.1f MiB\n",
      argv[1], (unsigned long long)clashes, (unsigned long long)groups, (unsigned long long)snapshots,
      std::chrono::duration<double>(t1 - t0).count(), rss_start, rss_run,
      std::chrono::duration<double>(t2 - t1).count(), bytes / 1048576.0, PeakRssMiB());
  return 0;
}
