#include "engine/viz/clash_render.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "engine/store_format/leaf_source.h"
#include "storage/atomic_file.h"

namespace mktree {

Rgb ClashColour(ClashMark c) {
  switch (c) {
    case ClashMark::kHard:
      return {225, 25, 25};
    case ClashMark::kTouch:
      return {250, 130, 0};
    case ClashMark::kClearance:
      return {235, 200, 0};
    case ClashMark::kNone:
      break;
  }
  return {175, 175, 175};
}

Result<Box3f> StoredObjectBox(const StoreReader& store, uint64_t id) {
  if (id >= store.object_count())
    return Status::InvalidArgument(store.path() + ": no object " + std::to_string(id));
  MKTREE_ASSIGN_OR_RETURN(const uint32_t leaf, store.ObjectLeaf(static_cast<ObjectId>(id)));
  PageCache cache(&store.pages(), 0);
  PinnedLeaf read;
  MKTREE_RETURN_IF_ERROR(LeafSource(store, cache, /*verify_checksums=*/true).Read(leaf, nullptr, &read));
  for (const ObjectEntryView& e : read.view.entries())
    if (e.id == id) return e.box;
  return Status::Corruption(store.path() + ": object " + std::to_string(id) + " is not in its leaf " +
                            std::to_string(leaf));
}

namespace {

// Layers of the rasterizer: the neutral scene, then the classes by severity, then the focus pair.
constexpr uint8_t kFocusLayer = kClashMarks;
// How far the neutral scene is blended toward white.
constexpr double kNeutralFade = 0.45;

// `box` grown by 15 % of its largest side (1 unit if it is a point).
Box3f GrownFocusBox(Box3f box) {
  float side = 0;
  for (int k = 0; k < 3; ++k) side = std::max(side, box.max[k] - box.min[k]);
  const float grow = side > 0 ? 0.15f * side : 1.0f;
  for (int k = 0; k < 3; ++k) box.min[k] -= grow, box.max[k] += grow;
  return box;
}

// The union of the focus pair's boxes (*pair), and that grown (GrownFocusBox).
Result<Box3f> FocusBox(const StoreReader& store, const MarkedPair& p, Box3f* pair) {
  auto a = StoredObjectBox(store, p.a);
  if (!a.ok()) return a.status();
  auto b = StoredObjectBox(store, p.b);
  if (!b.ok()) return b.status();
  Box3f box;
  for (int k = 0; k < 3; ++k) {
    box.min[k] = std::min(a->min[k], b->min[k]);
    box.max[k] = std::max(a->max[k], b->max[k]);
  }
  *pair = box;
  return GrownFocusBox(box);
}

// Whether `b` lies wholly nearer the viewer than `frame` (e.g. a storey above the framed box in a top view).
bool NearerThan(const Box3f& b, const Box3f& frame, RenderView view) {
  const viz::ViewAxes ax = viz::AxesOf(view);
  return ax.toward_sign > 0 ? b.min[ax.toward] > frame.max[ax.toward]
                            : b.max[ax.toward] < frame.min[ax.toward];
}

}  // namespace

Result<ClashRenderReport> RenderClashes(const StoreReader& store, const ClashMarks& marks,
                                        const std::string& png_path, const ClashRenderOptions& o) {
  if (o.width < 64 || o.height < 64 || o.width > 16384 || o.height > 16384)
    return Status::InvalidArgument("image " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                   ": width and height must be between 64 and 16384");
  const MKTree& tree = store.tree();
  if (tree.empty()) return Status::InvalidArgument(store.path() + ": empty store");
  if (marks.worst.size() != store.object_count())
    return Status::InvalidArgument(store.path() + ": the clash marks were read for " +
                                   std::to_string(marks.worst.size()) + " objects, the store has " +
                                   std::to_string(store.object_count()));
  if (o.focus && !marks.focus) return Status::InvalidArgument("focus asked for without a focus pair");
  ClashRenderReport report;
  report.framed = tree.nodes[0].box;
  if (o.focus && o.focus_box) {
    if (o.focus_box->empty()) return Status::InvalidArgument("focus box is empty");
    report.pair_box = *o.focus_box;
    report.framed = GrownFocusBox(*o.focus_box);
  } else if (o.focus) {
    auto box = FocusBox(store, *marks.focus, &report.pair_box);
    if (!box.ok()) return box.status();
    report.framed = *box;
  }
  // Open the output first: an unwritable path fails before any rendering work.
  auto out = AtomicFile::Create(png_path);
  if (!out.ok()) return out.status();
  report.samples_per_pixel = uint64_t{o.width} * o.height <= (uint64_t{4} << 20) ? 2 : 1;
  const uint32_t ss = report.samples_per_pixel;

  // Legend: reserve its lines with the widest counts it could show, so it never overlaps the scene.
  const int s = o.width >= 900 && o.height >= 300 ? 2 : 1;
  const int margin = std::max(6, static_cast<int>(std::min(o.width, o.height) / 40));
  auto legend_items = [&](const std::array<uint64_t, kClashMarks>& objects, bool widest, int bar_px,
                          double bar_len) {
    auto num = [&](uint64_t v) { return widest ? std::string(12, '0') : std::to_string(v); };
    std::vector<viz::LegendItem> items;
    std::string title = "CLASHES";
    if (o.focus && !o.focus_title.empty())
      title = o.focus_title;
    else if (o.focus)
      title = "PAIR " + std::to_string(marks.focus->a) + ", " + std::to_string(marks.focus->b) + " (" +
              ClashMarkName(marks.focus->cls) + ", LINE " + std::to_string(marks.focus->line) + ")";
    items.push_back({viz::LegendItem::kTitle, {}, title + ", " + RenderViewName(o.view) + " VIEW:"});
    for (ClashMark c : {ClashMark::kHard, ClashMark::kTouch, ClashMark::kClearance}) {
      const int i = static_cast<int>(c);
      items.push_back({viz::LegendItem::kSwatch, ClashColour(c),
                       std::string(ClashMarkName(c)) + " " + num(marks.pairs[i]) + " PAIRS, " +
                           num(objects[i]) + " OBJECTS"});
    }
    items.push_back({viz::LegendItem::kSwatch, ClashColour(ClashMark::kNone),
                     "NO CLASH " + num(objects[0]) + " OBJECTS"});
    char len[32];
    std::snprintf(len, sizeof len, "%g", bar_len);
    items.push_back({viz::LegendItem::kBar, {20, 20, 20}, widest ? "00000" : len, bar_px});
    return items;
  };
  const int legend_h =
      viz::LegendLines(legend_items({}, true, 150, 0), s, static_cast<int>(o.width), margin) * 11 * s + 4 * s;
  const double area_w = o.width - 2.0 * margin, area_h = o.height - 2.0 * margin - legend_h;
  if (area_h < 16)
    return Status::InvalidArgument("image " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                   " leaves no room for the picture above the legend");
  const viz::Frame f = viz::FitFrame(o.view, report.framed, margin, area_w, area_h);
  report.pixels_per_metre = f.scale;
  report.frame = f;
  const viz::Shader shader(f, report.framed);

  viz::Rasterizer raster(o.width * ss, o.height * ss);
  Mesh mesh;
  Status st = ForEachObjectAtLevel(
      store, 0,
      [&](uint32_t, const ObjectEntryView& e, LevelGroup) -> Status {
        ClashMark c = marks.Of(e.id);
        ++report.objects[static_cast<int>(c)];
        uint8_t layer = static_cast<uint8_t>(c);
        double fade = c == ClashMark::kNone ? kNeutralFade : 0.0;
        if (o.focus) {
          if (e.id == marks.focus->a || e.id == marks.focus->b) {
            c = marks.focus->cls;
            layer = kFocusLayer;
          } else if (!o.focus_box || c == ClashMark::kNone) {
            fade = kNeutralFade;  // the other pairs stay visible, but behind the focus pair in emphasis too
          }
        }
        if (o.focus_box && c == ClashMark::kNone && NearerThan(e.box, report.framed, o.view))
          return Status::Ok();
        MKTREE_RETURN_IF_ERROR(DecodeStoredMesh(store, e, &mesh));
        report.triangles += shader.Draw(mesh, ClashColour(c), e.id, layer, ss, &raster, fade);
        return Status::Ok();
      },
      o.progress);
  if (!st.ok()) return st;

  viz::Picture pic(o.width, o.height);
  raster.Outline();
  raster.Resolve(ss, &pic);
  if (o.focus) {  // the rest of the scene runs past the framed box: keep margins and legend strip clear
    const int W = static_cast<int>(o.width), H = static_cast<int>(o.height);
    const int right = margin + static_cast<int>(area_w), bottom = margin + static_cast<int>(area_h);
    pic.FillRect(0, 0, W - 1, margin - 1, viz::kBackground, 1);
    pic.FillRect(0, bottom, W - 1, H - 1, viz::kBackground, 1);
    pic.FillRect(0, margin, margin - 1, bottom - 1, viz::kBackground, 1);
    pic.FillRect(right, margin, W - 1, bottom - 1, viz::kBackground, 1);
    // A frame around the pair, so that the eye finds it at once.
    double x0, y0, x1, y1;
    f.Rect(report.pair_box, &x0, &y0, &x1, &y1);
    const int gap = 3;
    pic.OutlineRect(static_cast<int>(std::floor(x0)) - gap, static_cast<int>(std::floor(y0)) - gap,
                    static_cast<int>(std::ceil(x1)) + gap, static_cast<int>(std::ceil(y1)) + gap,
                    {20, 20, 20}, 1);
  }
  const double bar_len = viz::RoundLength(std::min(150.0, area_w / 4), f.scale);
  const int bar_px = std::max(2, static_cast<int>(std::lround(bar_len * f.scale)));
  viz::DrawLegend(&pic, legend_items(report.objects, false, bar_px, bar_len), s,
                  static_cast<int>(o.height) - margin - legend_h + 4 * s, margin);
  MKTREE_RETURN_IF_ERROR(viz::CommitPng(out->get(), o.width, o.height, pic.rgb()));
  return report;
}

}  // namespace mktree
