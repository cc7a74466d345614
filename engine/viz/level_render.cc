#include "engine/viz/level_render.h"

#include <png.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "engine/store/leaf_reader.h"
#include "engine/tree/split_tree_walk.h"
#include "storage/atomic_file.h"

namespace mktree {

const char* RenderViewName(RenderView v) {
  switch (v) {
    case RenderView::kTop:
      return "top";
    case RenderView::kSide:
      return "side";
    case RenderView::kFront:
      return "front";
  }
  return "?";
}

namespace {

// Encodes the image into `out` and commits it.
Status CommitPng(AtomicFile* out, uint32_t width, uint32_t height, const std::vector<uint8_t>& rgb) {
  const std::string& path = out->target();
  if (rgb.size() != size_t{3} * width * height)
    return Status::Internal(path + ": image buffer size mismatch");
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = width;
  image.height = height;
  image.format = PNG_FORMAT_RGB;
  // libpng writes to a stdio stream: one whose writes go to the AtomicFile (a glibc cookie stream), so the
  // PNG streams out as it is compressed.
  struct Sink {
    AtomicFile* out;
    Status status;
  } sink{out, Status::Ok()};
  cookie_io_functions_t io{};
  io.write = [](void* cookie, const char* buf, size_t n) -> ssize_t {
    auto* s = static_cast<Sink*>(cookie);
    if (s->status.ok()) s->status = s->out->Write(buf, n);
    return s->status.ok() ? static_cast<ssize_t>(n) : -1;
  };
  std::FILE* f = ::fopencookie(&sink, "wb", io);
  if (!f) return Status::IOError(path + ": writing the PNG failed: " + std::strerror(errno));
  const bool written = png_image_write_to_stdio(&image, f, 0, rgb.data(), 0, nullptr);
  const std::string why = written ? "" : image.message;
  png_image_free(&image);
  const bool closed = std::fclose(f) == 0;  // writes what the stream buffers
  MKTREE_RETURN_IF_ERROR(sink.status);
  if (!written) return Status::IOError(path + ": writing the PNG failed: " + why);
  if (!closed) return Status::IOError(path + ": writing the PNG failed: " + std::strerror(errno));
  return out->Commit();
}

constexpr Rgb kBackground{255, 255, 255};

// A 5x7 bitmap font for the legend (rows top to bottom, bit 4 = leftmost column). Upper case only.
struct Glyph {
  char c;
  uint8_t rows[7];
};
constexpr Glyph kFont[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}}, {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}}, {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}}, {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}}, {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}}, {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'A', {0x0E, 0x11, 0x11, 0x11, 0x1F, 0x11, 0x11}}, {'B', {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E}},
    {'C', {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E}}, {'D', {0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C}},
    {'E', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F}}, {'F', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10}},
    {'G', {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F}}, {'H', {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}},
    {'I', {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}}, {'J', {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C}},
    {'K', {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11}}, {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F}},
    {'M', {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11}}, {'N', {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11}},
    {'O', {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}}, {'P', {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10}},
    {'Q', {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D}}, {'R', {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11}},
    {'S', {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E}}, {'T', {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}},
    {'U', {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}}, {'V', {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04}},
    {'W', {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A}}, {'X', {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11}},
    {'Y', {0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04}}, {'Z', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F}},
    {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}}, {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}},
    {':', {0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00}}, {'-', {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}}, {',', {0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08}},
    {'=', {0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00}}, {'/', {0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00}},
    {'<', {0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02}}, {'>', {0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08}},
    {'%', {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03}},
};

const Glyph* FindGlyph(char c) {
  c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  for (const Glyph& g : kFont)
    if (g.c == c) return &g;
  return nullptr;  // space and anything unknown: blank
}

// The output picture (after downsampling), with the 2-D drawing the overlay and legend need.
class Picture {
 public:
  Picture(uint32_t w, uint32_t h) : w_(w), h_(h), rgb_(size_t{3} * w * h) {}
  uint32_t width() const { return w_; }
  uint32_t height() const { return h_; }
  std::vector<uint8_t>& rgb() { return rgb_; }

  void Blend(int x, int y, Rgb c, double alpha) {
    if (x < 0 || y < 0 || x >= static_cast<int>(w_) || y >= static_cast<int>(h_)) return;
    uint8_t* p = &rgb_[3 * (size_t{static_cast<uint32_t>(y)} * w_ + static_cast<uint32_t>(x))];
    p[0] = static_cast<uint8_t>(std::lround(p[0] + (c.r - p[0]) * alpha));
    p[1] = static_cast<uint8_t>(std::lround(p[1] + (c.g - p[1]) * alpha));
    p[2] = static_cast<uint8_t>(std::lround(p[2] + (c.b - p[2]) * alpha));
  }
  void FillRect(int x0, int y0, int x1, int y1, Rgb c, double alpha) {  // inclusive corners
    for (int y = std::max(y0, 0); y <= std::min(y1, static_cast<int>(h_) - 1); ++y)
      for (int x = std::max(x0, 0); x <= std::min(x1, static_cast<int>(w_) - 1); ++x) Blend(x, y, c, alpha);
  }
  void OutlineRect(int x0, int y0, int x1, int y1, Rgb c, double alpha) {
    for (int x = x0; x <= x1; ++x) Blend(x, y0, c, alpha), Blend(x, y1, c, alpha);
    for (int y = y0 + 1; y < y1; ++y) Blend(x0, y, c, alpha), Blend(x1, y, c, alpha);
  }
  // 5x7 text at scale s; returns the advance in pixels.
  int Text(int x, int y, const std::string& s, Rgb c, int scale) {
    for (size_t i = 0; i < s.size(); ++i) {
      if (const Glyph* g = FindGlyph(s[i]))
        for (int r = 0; r < 7; ++r)
          for (int col = 0; col < 5; ++col)
            if (g->rows[r] & (0x10 >> col))
              FillRect(x + static_cast<int>(i) * 6 * scale + col * scale, y + r * scale,
                       x + static_cast<int>(i) * 6 * scale + col * scale + scale - 1,
                       y + r * scale + scale - 1, c, 1);
    }
    return TextWidth(s, scale);
  }
  static int TextWidth(const std::string& s, int scale) { return static_cast<int>(s.size()) * 6 * scale; }

 private:
  uint32_t w_, h_;
  std::vector<uint8_t> rgb_;
};

// World axes of the view: right, up, and toward the viewer (see the header).
struct ViewAxes {
  int right, up, toward;  // world axis index
  double right_sign, toward_sign;
};
ViewAxes AxesOf(RenderView v) {
  switch (v) {
    case RenderView::kTop:
      return {0, 1, 2, 1, 1};
    case RenderView::kSide:
      return {0, 2, 1, 1, -1};
    case RenderView::kFront:
      return {1, 2, 0, 1, 1};
  }
  return {0, 1, 2, 1, 1};
}

// Maps world coordinates to output pixels (x right, y down) and depth (larger = nearer the viewer).
struct Frame {
  ViewAxes axes;
  double u0 = 0, v1 = 0, scale = 1, ox = 0, oy = 0;
  double X(double u) const { return ox + (u - u0) * scale; }
  double Y(double v) const { return oy + (v1 - v) * scale; }
  double U(const double* p) const { return axes.right_sign * p[axes.right]; }
  double V(const double* p) const { return p[axes.up]; }
  double D(const double* p) const { return axes.toward_sign * p[axes.toward]; }
  // Projected rectangle of a box, in pixels (x0 <= x1, y0 <= y1).
  void Rect(const Box3f& b, double* x0, double* y0, double* x1, double* y1) const {
    const double ua = axes.right_sign * b.min[axes.right], ub = axes.right_sign * b.max[axes.right];
    *x0 = X(std::min(ua, ub));
    *x1 = X(std::max(ua, ub));
    *y0 = Y(b.max[axes.up]);
    *y1 = Y(b.min[axes.up]);
  }
};

// Depth-buffered, conservative triangle rasterizer over a grid of samples.
class Rasterizer {
 public:
  static constexpr uint32_t kNoObject = 0xffffffffu;
  Rasterizer(uint32_t w, uint32_t h)
      : w_(w),
        h_(h),
        depth_(size_t{w} * h, -std::numeric_limits<float>::infinity()),
        colour_(size_t{w} * h, kBackground),
        object_(size_t{w} * h, kNoObject) {}

  // Vertices in sample coordinates (x right, y down) with depth d (larger = nearer).
  void Triangle(double ax, double ay, double ad, double bx, double by, double bd, double cx, double cy,
                double cd, Rgb c, uint32_t object) {
    double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    if (area == 0 || !std::isfinite(area)) return;  // edge-on: the object's other faces show it
    if (area < 0) {
      std::swap(bx, cx), std::swap(by, cy), std::swap(bd, cd);
      area = -area;
    }
    const double minx = std::min({ax, bx, cx}), maxx = std::max({ax, bx, cx});
    const double miny = std::min({ay, by, cy}), maxy = std::max({ay, by, cy});
    const int x0 = std::max(0, static_cast<int>(std::floor(minx))),
              x1 = std::min<int>(w_ - 1, static_cast<int>(std::floor(maxx)));
    const int y0 = std::max(0, static_cast<int>(std::floor(miny))),
              y1 = std::min<int>(h_ - 1, static_cast<int>(std::floor(maxy)));
    if (x0 > x1 || y0 > y1) return;
    // Edge e(p) = (q - p0) x (p - p0) for each edge p0 -> q; inside when all three are >= 0. Conservative:
    // accept a sample when the edge passes within its half-sample square (margin = L1 norm of the edge / 2).
    struct Edge {
      double ex, ey, px, py, margin;
      double At(double x, double y) const { return ex * (y - py) - ey * (x - px) + margin; }
    };
    const Edge e[3] = {
        {cx - bx, cy - by, bx, by, 0.5 * (std::abs(cx - bx) + std::abs(cy - by))},   // weight of a
        {ax - cx, ay - cy, cx, cy, 0.5 * (std::abs(ax - cx) + std::abs(ay - cy))},   // weight of b
        {bx - ax, by - ay, ax, ay, 0.5 * (std::abs(bx - ax) + std::abs(by - ay))}};  // weight of c
    const double dmin = std::min({ad, bd, cd}), dmax = std::max({ad, bd, cd});
    for (int y = y0; y <= y1; ++y) {
      const double sy = y + 0.5;
      for (int x = x0; x <= x1; ++x) {
        const double sx = x + 0.5;
        const double wa = e[0].At(sx, sy), wb = e[1].At(sx, sy), wc = e[2].At(sx, sy);
        if (wa < 0 || wb < 0 || wc < 0) continue;
        // Depth from the exact barycentric weights, clamped: conservative samples lie just outside.
        const double la = wa - e[0].margin, lb = wb - e[1].margin, lc = wc - e[2].margin;
        const float d = static_cast<float>(std::clamp((la * ad + lb * bd + lc * cd) / area, dmin, dmax));
        const size_t i = size_t{static_cast<uint32_t>(y)} * w_ + static_cast<uint32_t>(x);
        if (d > depth_[i]) {
          depth_[i] = d;
          colour_[i] = c;
          object_[i] = object;
        }
      }
    }
  }

  // Outlines every object: a sample whose right or lower neighbour shows another object (or the
  // background) is darkened on the nearer side, so plates, tiles and pipes read as separate shapes even
  // where they lie flush and share a colour.
  void Outline() {
    auto darken = [&](size_t i) {
      Rgb& c = colour_[i];
      c = {static_cast<uint8_t>(c.r * 0.55), static_cast<uint8_t>(c.g * 0.55),
           static_cast<uint8_t>(c.b * 0.55)};
    };
    std::vector<uint8_t> edge(colour_.size(), 0);
    for (uint32_t y = 0; y < h_; ++y)
      for (uint32_t x = 0; x < w_; ++x) {
        const size_t i = size_t{y} * w_ + x;
        for (const size_t j : {x + 1 < w_ ? i + 1 : i, y + 1 < h_ ? i + w_ : i}) {
          if (object_[i] == object_[j]) continue;
          const size_t front = depth_[i] >= depth_[j] ? i : j;
          if (object_[front] != kNoObject) edge[front] = 1;
        }
      }
    for (size_t i = 0; i < edge.size(); ++i)
      if (edge[i]) darken(i);
  }

  // Averages ss x ss samples into each pixel of `out`.
  void Resolve(uint32_t ss, Picture* out) const {
    std::vector<uint8_t>& rgb = out->rgb();
    for (uint32_t y = 0; y < out->height(); ++y)
      for (uint32_t x = 0; x < out->width(); ++x) {
        uint32_t r = 0, g = 0, b = 0;
        for (uint32_t j = 0; j < ss; ++j)
          for (uint32_t i = 0; i < ss; ++i) {
            const Rgb& c = colour_[size_t{y * ss + j} * w_ + x * ss + i];
            r += c.r, g += c.g, b += c.b;
          }
        const uint32_t n = ss * ss;
        uint8_t* p = &rgb[3 * (size_t{y} * out->width() + x)];
        p[0] = static_cast<uint8_t>((r + n / 2) / n);
        p[1] = static_cast<uint8_t>((g + n / 2) / n);
        p[2] = static_cast<uint8_t>((b + n / 2) / n);
      }
  }

 private:
  uint32_t w_, h_;
  std::vector<float> depth_;
  std::vector<Rgb> colour_;
  std::vector<uint32_t> object_;  // id of the object seen at each sample (for outlines)
};

std::string Count(uint64_t n) { return std::to_string(n); }

// A round length (1, 2 or 5 times a power of ten) that spans about `target_px` pixels.
double RoundLength(double target_px, double scale) {
  const double raw = target_px / scale;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * p <= raw) return m * p;
  return p;
}

constexpr Rgb kNodeBox{0, 0, 0}, kSlab{0, 100, 30}, kBothCell{255, 150, 0}, kCell{60, 60, 60};

// Hatching: slabs one way, BOTH cells the other, so the objects' colours stay readable underneath.
bool SlabHatch(int x, int y) { return (x + y) % 7 == 0; }
bool BothHatch(int x, int y) { return ((x - y) % 5 + 5) % 5 == 0; }

struct LegendItem {
  enum Kind { kSwatch, kOutline, kSlabHatch, kBothHatch, kBar, kTitle } kind;
  Rgb colour;
  std::string text;
  int bar_px = 0;
};

int ItemWidth(const LegendItem& it, int s) {
  const int swatch = it.kind == LegendItem::kTitle ? 0
                     : it.kind == LegendItem::kBar ? it.bar_px + 6 * s
                                                   : 13 * s;
  return swatch + Picture::TextWidth(it.text, s) + 18 * s;
}

// Lines the legend takes at scale s in `width` pixels.
int LegendLines(const std::vector<LegendItem>& items, int s, int width, int margin) {
  int lines = 1, x = margin;
  for (const LegendItem& it : items) {
    const int w = ItemWidth(it, s);
    if (x + w > width - margin && x > margin) ++lines, x = margin;
    x += w;
  }
  return lines;
}

void DrawLegend(Picture* pic, const std::vector<LegendItem>& items, int s, int top, int margin) {
  int x = margin, y = top;
  const int line_h = 11 * s;
  for (const LegendItem& it : items) {
    const int w = ItemWidth(it, s);
    if (x + w > static_cast<int>(pic->width()) - margin && x > margin) x = margin, y += line_h;
    const int sw = 9 * s;  // swatch side
    switch (it.kind) {
      case LegendItem::kSwatch:
        pic->FillRect(x, y - s, x + sw - 1, y + sw - 1 - s, it.colour, 1);
        x += 13 * s;
        break;
      case LegendItem::kOutline:
        pic->OutlineRect(x, y - s, x + sw - 1, y + sw - 1 - s, it.colour, 1);
        x += 13 * s;
        break;
      case LegendItem::kSlabHatch:
      case LegendItem::kBothHatch:
        for (int yy = y - s; yy < y + sw - s; ++yy)
          for (int xx = x; xx < x + sw; ++xx)
            if (it.kind == LegendItem::kSlabHatch ? SlabHatch(xx, yy) : BothHatch(xx, yy))
              pic->Blend(xx, yy, it.colour, 1);
        pic->OutlineRect(x, y - s, x + sw - 1, y + sw - 1 - s, it.colour, 1);
        x += 13 * s;
        break;
      case LegendItem::kBar:
        pic->FillRect(x, y + 3 * s, x + it.bar_px - 1, y + 4 * s - 1, it.colour, 1);
        pic->FillRect(x, y, x + s - 1, y + 7 * s - 1, it.colour, 1);
        pic->FillRect(x + it.bar_px - s, y, x + it.bar_px - 1, y + 7 * s - 1, it.colour, 1);
        x += it.bar_px + 6 * s;
        break;
      case LegendItem::kTitle:
        break;
    }
    x += pic->Text(x, y, it.text, {20, 20, 20}, s) + 18 * s;
  }
}

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
      if ((m & kInSlab) && SlabHatch(x, y)) pic->Blend(x, y, kSlab, 0.75);
      if ((m & kInBoth) && BothHatch(x, y)) pic->Blend(x, y, kBothCell, 0.9);
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
  Frame f;
  f.axes = AxesOf(o.view);
  const Box3f& bounds = tree.nodes[0].box;
  const double ua = f.axes.right_sign * bounds.min[f.axes.right],
               ub = f.axes.right_sign * bounds.max[f.axes.right];
  const double u0 = std::min(ua, ub), u1 = std::max(ua, ub);
  const double v0 = bounds.min[f.axes.up], v1 = bounds.max[f.axes.up];
  const double area_w = o.width - 2.0 * margin, area_h = o.height - 2.0 * margin - legend_h;
  if (area_h < 16)
    return Status::InvalidArgument("image " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                   " leaves no room for the picture above the legend");
  const double su = u1 > u0 ? area_w / (u1 - u0) : std::numeric_limits<double>::infinity();
  const double sv = v1 > v0 ? area_h / (v1 - v0) : std::numeric_limits<double>::infinity();
  f.scale = std::isfinite(std::min(su, sv)) ? std::min(su, sv) : 1.0;
  f.u0 = u0;
  f.v1 = v1;
  f.ox = margin + (area_w - (u1 - u0) * f.scale) / 2;
  f.oy = margin + (area_h - (v1 - v0) * f.scale) / 2;
  report.pixels_per_metre = f.scale;
  const double d_lo = std::min(f.axes.toward_sign * bounds.min[f.axes.toward],
                               f.axes.toward_sign * bounds.max[f.axes.toward]);
  const double d_span =
      std::max(1e-9, std::abs(double{bounds.max[f.axes.toward]} - bounds.min[f.axes.toward]));

  // Light from the viewer, a little from the right and the top of the picture: faces of different
  // orientation get different shades, so shapes read.
  double light[3] = {0, 0, 0};
  light[f.axes.toward] += 0.80 * f.axes.toward_sign;
  light[f.axes.right] += 0.35 * f.axes.right_sign;
  light[f.axes.up] += 0.50;
  const double ll = std::sqrt(light[0] * light[0] + light[1] * light[1] + light[2] * light[2]);
  for (double& c : light) c /= ll;

  Rasterizer raster(o.width * ss, o.height * ss);
  Mesh mesh;
  Status st = ForEachObjectAtLevel(
      store, o.level,
      [&](uint32_t, const ObjectEntryView& e, LevelGroup g) -> Status {
        ++report.objects[GroupIndex(g)];
        MKTREE_RETURN_IF_ERROR(DecodeStoredMesh(store.path(), e, &mesh));
        const Rgb base = GroupColour(g);
        for (size_t t = 0; t < mesh.triangle_count(); ++t) {
          const double* p[3];
          for (int k = 0; k < 3; ++k) p[k] = &mesh.vertices[3 * size_t{mesh.triangles[3 * t + k]}];
          double e1[3], e2[3];
          for (int k = 0; k < 3; ++k) e1[k] = p[1][k] - p[0][k], e2[k] = p[2][k] - p[0][k];
          const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                               e1[0] * e2[1] - e1[1] * e2[0]};
          const double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
          if (nl == 0) continue;
          const double lambert = std::abs(n[0] * light[0] + n[1] * light[1] + n[2] * light[2]) / nl;
          // Depth cue: nearer the viewer is lighter, so stacked decks and equipment separate.
          const double dc = (f.D(p[0]) + f.D(p[1]) + f.D(p[2])) / 3;
          const double cue = 0.72 + 0.28 * std::clamp((dc - d_lo) / d_span, 0.0, 1.0);
          const double shade = (0.40 + 0.60 * lambert) * cue;
          const Rgb c{static_cast<uint8_t>(base.r * shade), static_cast<uint8_t>(base.g * shade),
                      static_cast<uint8_t>(base.b * shade)};
          raster.Triangle(f.X(f.U(p[0])) * ss, f.Y(f.V(p[0])) * ss, f.D(p[0]), f.X(f.U(p[1])) * ss,
                          f.Y(f.V(p[1])) * ss, f.D(p[1]), f.X(f.U(p[2])) * ss, f.Y(f.V(p[2])) * ss, f.D(p[2]),
                          c, e.id);
          ++report.triangles;
        }
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
