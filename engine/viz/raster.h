// The drawing parts the PNG pictures share (`mktree render --level` in level_render.h and
// `mktree render --clashes` in clash_render.h): the view frames, the conservative z-buffered triangle
// rasterizer with flat shading, object outlines and 2 x 2 supersampling, the picture with its 5x7 bitmap
// font, the legend strip, and the PNG writer. Internal to engine/viz.
//
// Thread safety: objects are not shared; the free functions are pure.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/viz/level_colouring.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"
#include "mktree/status.h"
#include "storage/atomic_file.h"

namespace mktree {

enum class RenderView { kTop, kSide, kFront };
// "top", "side", "front".
const char* RenderViewName(RenderView v);

namespace viz {

inline constexpr Rgb kBackground{255, 255, 255};

// Encodes the image (rows top to bottom, 3 bytes a pixel) into `out` and commits it.
Status CommitPng(AtomicFile* out, uint32_t width, uint32_t height, const std::vector<uint8_t>& rgb);

// The output picture (after downsampling), with the 2-D drawing that overlays and legends need.
class Picture {
 public:
  Picture(uint32_t w, uint32_t h) : w_(w), h_(h), rgb_(size_t{3} * w * h) {}
  uint32_t width() const { return w_; }
  uint32_t height() const { return h_; }
  std::vector<uint8_t>& rgb() { return rgb_; }

  void Blend(int x, int y, Rgb c, double alpha);
  void FillRect(int x0, int y0, int x1, int y1, Rgb c, double alpha);  // inclusive corners
  void OutlineRect(int x0, int y0, int x1, int y1, Rgb c, double alpha);
  // 5x7 text at scale s (upper case, digits and a little punctuation); returns the advance in pixels.
  int Text(int x, int y, const std::string& s, Rgb c, int scale);
  static int TextWidth(const std::string& s, int scale) { return static_cast<int>(s.size()) * 6 * scale; }

 private:
  uint32_t w_, h_;
  std::vector<uint8_t> rgb_;
};

// World axes of a view: right, up, and toward the viewer (level_render.h lists the views).
struct ViewAxes {
  int right, up, toward;  // world axis index
  double right_sign, toward_sign;
};
ViewAxes AxesOf(RenderView v);

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
  void Rect(const Box3f& b, double* x0, double* y0, double* x1, double* y1) const;
};

// The frame that fits `bounds` (projected along `view`) into the area of area_w x area_h pixels whose top
// left corner is (margin, margin), centred, keeping the aspect ratio.
Frame FitFrame(RenderView view, const Box3f& bounds, int margin, double area_w, double area_h);

// Depth-buffered, conservative triangle rasterizer over a grid of samples. Each triangle has a layer:
// a sample shows the triangle of the highest layer that covers it, the nearest one within that layer
// (so highlighted objects can be drawn through the rest of the scene; one layer is a plain z-buffer).
class Rasterizer {
 public:
  static constexpr uint32_t kNoObject = 0xffffffffu;
  Rasterizer(uint32_t w, uint32_t h);

  // Vertices in sample coordinates (x right, y down) with depth d (larger = nearer).
  void Triangle(double ax, double ay, double ad, double bx, double by, double bd, double cx, double cy,
                double cd, Rgb c, uint32_t object, uint8_t layer = 0);

  // Outlines every object: a sample whose right or lower neighbour shows another object (or the
  // background) is darkened on the front side, so plates, tiles and pipes read as separate shapes even
  // where they lie flush and share a colour.
  void Outline();

  // Averages ss x ss samples into each pixel of `out`.
  void Resolve(uint32_t ss, Picture* out) const;

 private:
  bool InFront(size_t i, size_t j) const {  // sample i shows something at least as near as sample j
    return layer_[i] != layer_[j] ? layer_[i] > layer_[j] : depth_[i] >= depth_[j];
  }
  uint32_t w_, h_;
  std::vector<float> depth_;
  std::vector<Rgb> colour_;
  std::vector<uint32_t> object_;  // id of the object seen at each sample (for outlines)
  std::vector<uint8_t> layer_;
};

// Flat shading of a scene's triangles: light from the viewer, a little from the right and the top of the
// picture, so faces of different orientation get different shades; and a depth cue (nearer is lighter)
// over the depth range of `bounds`, so stacked decks and equipment separate.
class Shader {
 public:
  Shader(const Frame& f, const Box3f& bounds);
  // Rasterizes every triangle of `mesh` (store frame) in `base` colour shaded; returns the count drawn.
  // `ss` is the samples per pixel along each axis; `fade` in [0, 1] blends the shaded colour toward white.
  uint64_t Draw(const Mesh& mesh, Rgb base, uint32_t object, uint8_t layer, uint32_t ss, Rasterizer* raster,
                double fade = 0) const;

 private:
  Frame f_;
  double light_[3] = {0, 0, 0};
  double d_lo_ = 0, d_span_ = 1;
};

// A round length (1, 2 or 5 times a power of ten) that spans about `target_px` pixels.
double RoundLength(double target_px, double scale);

// Hatching: overlap slabs one way, BOTH cells the other, so the objects' colours stay readable underneath.
inline bool SlabHatch(int x, int y) { return (x + y) % 7 == 0; }
inline bool BothHatch(int x, int y) { return ((x - y) % 5 + 5) % 5 == 0; }

struct LegendItem {
  enum Kind { kSwatch, kOutline, kSlabHatch, kBothHatch, kBar, kTitle } kind;
  Rgb colour;
  std::string text;
  int bar_px = 0;
};

// Lines the legend takes at scale s in `width` pixels.
int LegendLines(const std::vector<LegendItem>& items, int s, int width, int margin);
void DrawLegend(Picture* pic, const std::vector<LegendItem>& items, int s, int top, int margin);

}  // namespace viz
}  // namespace mktree
