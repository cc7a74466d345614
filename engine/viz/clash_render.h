// `mktree render --clashes`: the scene with its clashing objects highlighted, so that a person sees where
// the problems are. Every object of the store is drawn (leaf by leaf, as render --level does; views,
// projection, shading and outlines as in level_render.h): objects in no pair in a faded light grey, objects
// in a pair in the colour of their worst class (red hard, orange touch, yellow clearance).
//
// Highlighted objects are drawn through the rest: each class is a layer of the rasterizer (raster.h) above
// the neutral scene and above the milder classes, so a clashing pipe inside a wall, or under a deck in a
// top view, still shows, and a hard clash is never hidden by a touch. Within a layer the nearest surface
// wins, and outlines keep neighbouring objects apart. The neutral scene is faded toward white so the
// colours stand out, while its shading and outlines still give the context (which deck, which frame).
//
// With `focus`, the view is framed on the focus pair's two objects (the union of their boxes with a margin
// of 15 % of its largest side on each side) instead of the whole scene, and clipped to it; those two
// objects are drawn in the pair's class above everything else and outlined by a dark rectangle, every
// other object faded. A legend strip at
// the bottom: per class its pairs and objects, the objects in no pair, and a scale bar.
//
// Memory: the marks (one byte per object), the sample buffers (14 bytes a sample) and one leaf.
// Thread safety: RenderClashes only reads `store` and `marks`.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "engine/store_format/store_file.h"
#include "engine/viz/clash_pairs_file.h"
#include "engine/viz/level_colouring.h"
#include "engine/viz/raster.h"
#include "mktree/status.h"

namespace mktree {

// Red hard, orange touch, yellow clearance, light grey none.
Rgb ClashColour(ClashMark c);

struct ClashRenderOptions {
  RenderView view = RenderView::kTop;
  uint32_t width = 1600;  // pixels, 64..16384
  uint32_t height = 400;  // pixels, 64..16384
  bool focus = false;     // frame marks.focus (which must be set) instead of the whole scene
  // With focus, a group of pairs (engine/report/group_snapshot.h): frame and outline this box (store
  // frame) instead of the focus pair's, draw every marked object in its class unfaded, and title the
  // legend with `focus_title` (5x7 font: upper case, digits, little punctuation) instead of the pair;
  // unmarked objects wholly nearer the viewer than the framed box (the storeys above it in a top view) are
  // left out, as a section box would.
  std::optional<Box3f> focus_box;
  std::string focus_title;
  // Optional: (leaves done, leaves total).
  std::function<void(uint64_t, uint64_t)> progress;
};

struct ClashRenderReport {
  std::array<uint64_t, kClashMarks> objects{};  // objects drawn per colour (ClashMark)
  uint64_t triangles = 0;                       // triangles rasterized
  uint32_t samples_per_pixel = 1;
  double pixels_per_metre = 0;
  Box3f framed;      // the box fitted to the picture (store frame)
  Box3f pair_box;    // with focus: the union of the pair's boxes, outlined in the picture
  viz::Frame frame;  // store frame to output pixels
};

// Renders `store` with the objects of `marks` (read for this store: marks.worst has one byte per object)
// highlighted and writes an 8-bit RGB PNG at `png_path` (temporary file and rename: nothing half-written
// on error).
Result<ClashRenderReport> RenderClashes(const StoreReader& store, const ClashMarks& marks,
                                        const std::string& png_path, const ClashRenderOptions& options);

// The box of object `id` of `store` (store frame), read from its leaf.
Result<Box3f> StoredObjectBox(const StoreReader& store, uint64_t id);

}  // namespace mktree
