#include "engine/viz/level_render.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "engine/store_format/leaf_source.h"
#include "engine/tree/split_tree_walk.h"
#include "storage/atomic_file.h"

namespace mktree {

namespace {

using viz::CommitPng;
using viz::DrawLegend;
using viz::Frame;
using viz::LegendItem;
using viz::LegendLines;
using viz::Picture;
using viz::RoundLength;

std::string Count(uint64_t n) { return std::to_string(n); }

constexpr Rgb kNodeBox{0, 0, 0}, kSlab{0, 100, 30}, kBothCell{255, 150, 0}, kCell{60, 60, 60};

// Node boxes at depth k, their overlap slabs and SplitTree cells. Regions are first collected in masks
// and then drawn once, because the boxes overlap in projection (cells stacked along the view axis).
void DrawOverlay(const MKTree& tree, int k, const Frame& f, Picture* pic) {
  const int W = static_cast<int>(pic->width()), H = static_cast<int>(pic->height());
  enum : uint8_t { kInSlab = 1, kInBoth = 2, kCellEdge = 4 };
  std::vector<uint8_t> mask(size_t(W) * H, 0);
  auto rect = [&](const Box3f& b, int* x0, int* y0, int* x1, int* y1) {
    double a0, b0, a1, b1;
    f.Rect(b, &a0, &b0, &a1, &b1);
    *x0 = static_cast<int>(std::floor(a0)), *y0 = static_cast<int>(std::floor(b0));
    *x1 = std::max(*x0, static_cast<int>(std::ceil(a1)) - 1),
    *y1 = std::max(*y0, static_cast<int>(std::ceil(b1)) - 1);
  };
  auto mark = [&](const Box3f& b, uint8_t bit, bool edge_only) {
    int x0, y0, x1, y1;
    rect(b, &x0, &y0, &x1, &y1);
    for (int y = std::max(y0, 0); y <= std::min(y1, H - 1); ++y)
      for (int x = std::max(x0, 0); x <= std::min(x1, W - 1); ++x)
        if (!edge_only || x == x0 || x == x1 || y == y0 || y == y1) mask[size_t(y) * W + x] |= bit;
  };
  std::vector<Box3f> slabs;
  for (const TreeNode& n : tree.nodes) {
    if (n.depth != k || n.is_leaf()) continue;
    const int w = n.axis;
    Box3f slab = n.box;
    if (n.a >= n.b) {  // disjoint children: the gap between them, drawn as the plane halfway
      slab.min[w] = slab.max[w] = 0.5f * (n.a + n.b);
      slabs.push_back(slab);
      continue;
    }
    slab.min[w] = n.a;
    slab.max[w] = n.b;
    slabs.push_back(slab);
    mark(slab, kInSlab, false);
    // SplitTree cells inside the slab: BOTH cells are where a query must visit both children.
    if (n.split_root == kNoIndex) continue;
    ForEachSplitCell(tree.split_nodes, n.split_root, SplitRegion{slab},
                     [&](const SplitNode& cell, const Box3f& region) {
                       if (cell.label == CellLabel::kBoth) mark(region, kInBoth, false);
                       mark(region, kCellEdge, true);
                       return true;
                     });
  }
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const uint8_t m = mask[size_t(y) * W + x];
      if (m & kCellEdge) pic->Blend(x, y, kCell, 0.45);
      if ((m & kInSlab) && viz::SlabHatch(x, y)) pic->Blend(x, y, kSlab, 0.75);
      if ((m & kInBoth) && viz::BothHatch(x, y)) pic->Blend(x, y, kBothCell, 0.9);
    }
  int x0, y0, x1, y1;
  for (const Box3f& slab : slabs) {
    rect(slab, &x0, &y0, &x1, &y1);
    pic->OutlineRect(x0, y0, x1, y1, kSlab, 1);
  }
  for (const TreeNode& n : tree.nodes) {
    if (n.depth != k) continue;
    rect(n.box, &x0, &y0, &x1, &y1);
    pic->OutlineRect(x0, y0, x1, y1, kNodeBox, 1);
    pic->OutlineRect(x0 + 1, y0 + 1, x1 - 1, y1 - 1, kNodeBox, 1);
  }
}

}  // namespace

Status WriteRgbPng(const std::string& path, uint32_t width, uint32_t height,
                   const std::vector<uint8_t>& rgb) {
  auto out = AtomicFile::Create(path);
  if (!out.ok()) return out.status();
  return CommitPng(out->get(), width, height, rgb);
}

Result<RenderReport> RenderLevel(const StoreReader& store, const std::string& png_path,
                                 const RenderOptions& o) {
  if (o.level < 0) return Status::InvalidArgument("level " + std::to_string(o.level) + ": levels start at 0");
  if (o.width < 64 || o.height < 64 || o.width > 16384 || o.height > 16384)
    return Status::InvalidArgument("image " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                   ": width and height must be between 64 and 16384");
  const MKTree& tree = store.tree();
  if (tree.empty()) return Status::InvalidArgument(store.path() + ": empty store");
  // Open the output first: an unwritable path fails before any rendering work.
  auto out = AtomicFile::Create(png_path);
  if (!out.ok()) return out.status();
  RenderReport report;
  report.samples_per_pixel = uint64_t{o.width} * o.height <= (uint64_t{4} << 20) ? 2 : 1;
  const uint32_t ss = report.samples_per_pixel;

  // Legend: reserve its lines with the widest counts it could show, so it never overlaps the scene.
  const int s = o.width >= 900 && o.height >= 300 ? 2 : 1;
  const int margin = std::max(6, static_cast<int>(std::min(o.width, o.height) / 40));
  auto legend_items = [&](const GroupCounts& c, bool widest, int bar_px, double bar_len) {
    auto num = [&](uint64_t v) { return widest ? std::string(10, '0') : Count(v); };
    std::vector<LegendItem> items;
    items.push_back({LegendItem::kTitle,
                     {},
                     "LEVEL " + std::to_string(o.level) + ", " + RenderViewName(o.view) + " VIEW:"});
    const char* label[kLevelGroups] = {"SN1 SIDE", "SN2 SIDE", "OVERLAP SET SM", "LEAF AT DEPTH <= K"};
    for (int g = 0; g < kLevelGroups; ++g)
      items.push_back({LegendItem::kSwatch, GroupColour(static_cast<LevelGroup>(g)),
                       std::string(label[g]) + " " + num(c[g])});
    if (o.overlay) {
      items.push_back({LegendItem::kOutline, kNodeBox, "NODE AT DEPTH " + std::to_string(o.level)});
      items.push_back({LegendItem::kSlabHatch, kSlab, "OVERLAP SLAB"});
      items.push_back({LegendItem::kBothHatch, kBothCell, "SPLITTREE BOTH CELL"});
    }
    char len[32];
    std::snprintf(len, sizeof len, "%g", bar_len);
    items.push_back({LegendItem::kBar, {20, 20, 20}, widest ? "00000" : len, bar_px});
    return items;
  };
  const int legend_h =
      LegendLines(legend_items({}, true, 150, 0), s, static_cast<int>(o.width), margin) * 11 * s + 4 * s;

  // Fit the scene bounds into the drawing area above the legend, keeping the aspect ratio.
  const Box3f& bounds = tree.nodes[0].box;
  const double area_w = o.width - 2.0 * margin, area_h = o.height - 2.0 * margin - legend_h;
  if (area_h < 16)
    return Status::InvalidArgument("image " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                   " leaves no room for the picture above the legend");
  const Frame f = viz::FitFrame(o.view, bounds, margin, area_w, area_h);
  report.pixels_per_metre = f.scale;
  const viz::Shader shader(f, bounds);

  viz::Rasterizer raster(o.width * ss, o.height * ss);
  Mesh mesh;
  Status st = ForEachObjectAtLevel(
      store, o.level,
      [&](uint32_t, const ObjectEntryView& e, LevelGroup g) -> Status {
        ++report.objects[GroupIndex(g)];
        MKTREE_RETURN_IF_ERROR(DecodeStoredMesh(store, e, &mesh));
        report.triangles += shader.Draw(mesh, GroupColour(g), e.id, 0, ss, &raster);
        return Status::Ok();
      },
      o.progress);
  if (!st.ok()) return st;

  Picture pic(o.width, o.height);
  raster.Outline();
  raster.Resolve(ss, &pic);
  if (o.overlay) DrawOverlay(tree, o.level, f, &pic);
  const double bar_len = RoundLength(std::min(150.0, area_w / 4), f.scale);
  const int bar_px = std::max(2, static_cast<int>(std::lround(bar_len * f.scale)));
  DrawLegend(&pic, legend_items(report.objects, false, bar_px, bar_len), s,
             static_cast<int>(o.height) - margin - legend_h + 4 * s, margin);
  MKTREE_RETURN_IF_ERROR(CommitPng(out->get(), o.width, o.height, pic.rgb()));
  return report;
}

}  // namespace mktree
