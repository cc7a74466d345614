#include "engine/report/group_snapshot.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>

#include "engine/report/report_text.h"
#include "engine/viz/clash_render.h"

namespace mktree {

namespace {

ClashMark MarkOf(ClashClass c) {
  switch (c) {
    case ClashClass::kHard:
      return ClashMark::kHard;
    case ClashClass::kTouch:
      return ClashMark::kTouch;
    case ClashClass::kClearance:
      return ClashMark::kClearance;
  }
  return ClashMark::kHard;
}

// The legend's 5x7 font has upper case, digits and a little punctuation.
std::string LegendText(const std::string& s) {
  std::string out;
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    out.push_back(std::isalnum(u) ? static_cast<char>(std::toupper(u))
                                  : (std::strchr(".,:-()/", c) ? c : ' '));
  }
  return out.size() > 60 ? out.substr(0, 57) + "..." : out;
}

}  // namespace

Result<std::vector<uint8_t>> RenderGroupSnapshot(const StoreReader& store, const ClashGroup& group,
                                                 const GroupSnapshotOptions& o) {
  if (o.width < 64 || o.height < 64 || o.width > 1500 || o.height > 1500)
    return Status::InvalidArgument("snapshot " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                   ": width and height must be between 64 and 1500");
  if (group.members.empty()) return Status::InvalidArgument("clash group " + group.key + " has no members");
  ClashMarks marks;
  marks.worst.assign(store.object_count(), 0);
  const ClashRecord* worst = report::WorstMember(group);
  Box3f box;  // the members' objects' stored boxes (store frame)
  for (const ClashRecord& r : group.members) {
    if (r.a->id >= store.object_count() || r.b->id >= store.object_count())
      return Status::InvalidArgument(store.path() + ": clash group " + group.key + " names object " +
                                     std::to_string(std::max(r.a->id, r.b->id)) + ", past the store's " +
                                     std::to_string(store.object_count()) + " objects");
    const ClashMark m = MarkOf(r.pair.cls);
    ++marks.pairs[static_cast<int>(m)];
    for (ObjectId id : {r.a->id, r.b->id})
      marks.worst[id] = std::max(marks.worst[id], static_cast<uint8_t>(m));
  }
  const Vec3d& origin = store.tree().origin;
  for (int k = 0; k < 3 && !group.box.empty(); ++k) {  // the group's world box in the store frame
    box.min[k] = std::nextafter(static_cast<float>(group.box.min[k] - origin[k]), -INFINITY);
    box.max[k] = std::nextafter(static_cast<float>(group.box.max[k] - origin[k]), INFINITY);
  }
  for (ObjectId id = 0; id < marks.worst.size(); ++id) {
    ++marks.objects[marks.worst[id]];
    if (marks.worst[id] == 0 || !group.box.empty()) continue;
    auto b = StoredObjectBox(store, id);  // a group without a box: its objects' boxes
    if (!b.ok()) return b.status();
    box.Extend(*b);
  }
  marks.focus = MarkedPair{worst->a->id, worst->b->id, MarkOf(worst->pair.cls), 0};
  ClashRenderOptions ro;
  ro.view = o.view;
  ro.width = o.width;
  ro.height = o.height;
  ro.focus = true;
  ro.focus_box = box;
  ro.focus_title = LegendText(std::string(ClashClassName(group.worst)) + " group, " +
                              std::to_string(group.members.size()) + " clashes, " + group.test);
  static std::atomic<uint64_t> counter{0};
  const std::string png =
      (std::filesystem::temp_directory_path() /
       ("mktree-snapshot-" + std::to_string(::getpid()) + "-" + std::to_string(++counter) + ".png"))
          .string();
  auto rendered = RenderClashes(store, marks, png, ro);
  if (!rendered.ok()) return rendered.status();
  std::ifstream in(png, std::ios::binary);
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const bool read = in.good() || in.eof();
  in.close();
  std::filesystem::remove(png);
  if (!read || bytes.empty()) return Status::IOError(png + ": cannot read the rendered snapshot back");
  return bytes;
}

GroupSnapshotSource StoreSnapshotSource(const StoreReader& store, const GroupSnapshotOptions& options) {
  return [&store, options](const ClashGroup& g) { return RenderGroupSnapshot(store, g, options); };
}

GroupSnapshotSource MemoizedSnapshotSource(GroupSnapshotSource source, uint64_t max_groups) {
  auto kept = std::make_shared<std::map<std::string, std::vector<uint8_t>>>();
  return [source = std::move(source), kept, max_groups](const ClashGroup& g) -> Result<std::vector<uint8_t>> {
    if (auto it = kept->find(g.key); it != kept->end()) return it->second;
    auto png = source(g);
    if (png.ok() && kept->size() < max_groups) kept->emplace(g.key, *png);
    return png;
  };
}

}  // namespace mktree
