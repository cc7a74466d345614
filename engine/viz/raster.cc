#include "engine/viz/raster.h"

#include <png.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

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

namespace viz {

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

namespace {

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

}  // namespace

void Picture::Blend(int x, int y, Rgb c, double alpha) {
  if (x < 0 || y < 0 || x >= static_cast<int>(w_) || y >= static_cast<int>(h_)) return;
  uint8_t* p = &rgb_[3 * (size_t{static_cast<uint32_t>(y)} * w_ + static_cast<uint32_t>(x))];
  p[0] = static_cast<uint8_t>(std::lround(p[0] + (c.r - p[0]) * alpha));
  p[1] = static_cast<uint8_t>(std::lround(p[1] + (c.g - p[1]) * alpha));
  p[2] = static_cast<uint8_t>(std::lround(p[2] + (c.b - p[2]) * alpha));
}

void Picture::FillRect(int x0, int y0, int x1, int y1, Rgb c, double alpha) {
  for (int y = std::max(y0, 0); y <= std::min(y1, static_cast<int>(h_) - 1); ++y)
    for (int x = std::max(x0, 0); x <= std::min(x1, static_cast<int>(w_) - 1); ++x) Blend(x, y, c, alpha);
}

void Picture::OutlineRect(int x0, int y0, int x1, int y1, Rgb c, double alpha) {
  for (int x = x0; x <= x1; ++x) Blend(x, y0, c, alpha), Blend(x, y1, c, alpha);
  for (int y = y0 + 1; y < y1; ++y) Blend(x0, y, c, alpha), Blend(x1, y, c, alpha);
}

int Picture::Text(int x, int y, const std::string& s, Rgb c, int scale) {
  for (size_t i = 0; i < s.size(); ++i) {
    if (const Glyph* g = FindGlyph(s[i]))
      for (int r = 0; r < 7; ++r)
        for (int col = 0; col < 5; ++col)
          if (g->rows[r] & (0x10 >> col))
            FillRect(x + static_cast<int>(i) * 6 * scale + col * scale, y + r * scale,
                     x + static_cast<int>(i) * 6 * scale + col * scale + scale - 1, y + r * scale + scale - 1,
                     c, 1);
  }
  return TextWidth(s, scale);
}

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

void Frame::Rect(const Box3f& b, double* x0, double* y0, double* x1, double* y1) const {
  const double ua = axes.right_sign * b.min[axes.right], ub = axes.right_sign * b.max[axes.right];
  *x0 = X(std::min(ua, ub));
  *x1 = X(std::max(ua, ub));
  *y0 = Y(b.max[axes.up]);
  *y1 = Y(b.min[axes.up]);
}

Frame FitFrame(RenderView view, const Box3f& bounds, int margin, double area_w, double area_h) {
  Frame f;
  f.axes = AxesOf(view);
  const double ua = f.axes.right_sign * bounds.min[f.axes.right],
               ub = f.axes.right_sign * bounds.max[f.axes.right];
  const double u0 = std::min(ua, ub), u1 = std::max(ua, ub);
  const double v0 = bounds.min[f.axes.up], v1 = bounds.max[f.axes.up];
  const double su = u1 > u0 ? area_w / (u1 - u0) : std::numeric_limits<double>::infinity();
  const double sv = v1 > v0 ? area_h / (v1 - v0) : std::numeric_limits<double>::infinity();
  f.scale = std::isfinite(std::min(su, sv)) ? std::min(su, sv) : 1.0;
  f.u0 = u0;
  f.v1 = v1;
  f.ox = margin + (area_w - (u1 - u0) * f.scale) / 2;
  f.oy = margin + (area_h - (v1 - v0) * f.scale) / 2;
  return f;
}

Rasterizer::Rasterizer(uint32_t w, uint32_t h)
    : w_(w),
      h_(h),
      depth_(size_t{w} * h, -std::numeric_limits<float>::infinity()),
      colour_(size_t{w} * h, kBackground),
      object_(size_t{w} * h, kNoObject),
      layer_(size_t{w} * h, 0) {}

void Rasterizer::Triangle(double ax, double ay, double ad, double bx, double by, double bd, double cx,
                          double cy, double cd, Rgb c, uint32_t object, uint8_t layer) {
  double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
  if (area == 0 || !std::isfinite(area)) return;  // edge-on: the object's other faces show it
  if (area < 0) {
    std::swap(bx, cx), std::swap(by, cy), std::swap(bd, cd);
    area = -area;
  }
  const double minx = std::min({ax, bx, cx}), maxx = std::max({ax, bx, cx});
  const double miny = std::min({ay, by, cy}), maxy = std::max({ay, by, cy});
  // Culled before the casts: a focused view puts far triangles at coordinates no int holds.
  if (maxx < 0 || maxy < 0 || minx >= w_ || miny >= h_) return;
  const int x0 = static_cast<int>(std::floor(std::max(minx, 0.0))),
            x1 = static_cast<int>(std::floor(std::min(maxx, w_ - 1.0)));
  const int y0 = static_cast<int>(std::floor(std::max(miny, 0.0))),
            y1 = static_cast<int>(std::floor(std::min(maxy, h_ - 1.0)));
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
      if (layer > layer_[i] || (layer == layer_[i] && d > depth_[i])) {
        depth_[i] = d;
        colour_[i] = c;
        object_[i] = object;
        layer_[i] = layer;
      }
    }
  }
}

void Rasterizer::Outline() {
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
        const size_t front = InFront(i, j) ? i : j;
        if (object_[front] != kNoObject) edge[front] = 1;
      }
    }
  for (size_t i = 0; i < edge.size(); ++i)
    if (edge[i]) darken(i);
}

void Rasterizer::Resolve(uint32_t ss, Picture* out) const {
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

Shader::Shader(const Frame& f, const Box3f& bounds) : f_(f) {
  d_lo_ = std::min(f.axes.toward_sign * bounds.min[f.axes.toward],
                   f.axes.toward_sign * bounds.max[f.axes.toward]);
  d_span_ = std::max(1e-9, std::abs(double{bounds.max[f.axes.toward]} - bounds.min[f.axes.toward]));
  light_[f.axes.toward] += 0.80 * f.axes.toward_sign;
  light_[f.axes.right] += 0.35 * f.axes.right_sign;
  light_[f.axes.up] += 0.50;
  const double ll = std::sqrt(light_[0] * light_[0] + light_[1] * light_[1] + light_[2] * light_[2]);
  for (double& c : light_) c /= ll;
}

uint64_t Shader::Draw(const Mesh& mesh, Rgb base, uint32_t object, uint8_t layer, uint32_t ss,
                      Rasterizer* raster, double fade) const {
  const Frame& f = f_;
  const double* light = light_;
  uint64_t drawn = 0;
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
    const double dc = (f.D(p[0]) + f.D(p[1]) + f.D(p[2])) / 3;
    const double cue = 0.72 + 0.28 * std::clamp((dc - d_lo_) / d_span_, 0.0, 1.0);
    const double shade = (0.40 + 0.60 * lambert) * cue;
    Rgb c{static_cast<uint8_t>(base.r * shade), static_cast<uint8_t>(base.g * shade),
          static_cast<uint8_t>(base.b * shade)};
    if (fade > 0)
      for (uint8_t* v : {&c.r, &c.g, &c.b}) *v = static_cast<uint8_t>(*v + std::lround((255 - *v) * fade));
    raster->Triangle(f.X(f.U(p[0])) * ss, f.Y(f.V(p[0])) * ss, f.D(p[0]), f.X(f.U(p[1])) * ss,
                     f.Y(f.V(p[1])) * ss, f.D(p[1]), f.X(f.U(p[2])) * ss, f.Y(f.V(p[2])) * ss, f.D(p[2]), c,
                     object, layer);
    ++drawn;
  }
  return drawn;
}

// A round length (1, 2 or 5 times a power of ten) that spans about `target_px` pixels.
double RoundLength(double target_px, double scale) {
  const double raw = target_px / scale;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * p <= raw) return m * p;
  return p;
}

static int ItemWidth(const LegendItem& it, int s) {
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

}  // namespace viz
}  // namespace mktree
