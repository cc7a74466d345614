// `mktree render`: a picture of the level-k colouring (engine/viz/level_colouring.h), like the paper's
// figures of oil tankers: every object's triangles, projected orthographically along one axis, filled by a
// small software rasterizer with a z-buffer, coloured by the object's group (blue Sn1 side, red Sn2 side,
// green overlap set Sm, grey leaf at depth <= k) and flat-shaded by the face normal; a legend strip at the
// bottom. Optionally (`overlay`) the nodes at depth k on top: their boxes R(Sn), their overlap slabs
// (a <= w <= b, tinted) and their SplitTree cells (BOTH cells tinted yellow).
//
// Views (right-handed, the image is never mirrored):
//   top   : looking down -z; x to the right, y up the picture (a ship's plan).
//   side  : looking along +y from y = -inf; x to the right, z up.
//   front : looking along -x from x = +inf; y to the right, z up.
// The scene bounds (the root's box) are fitted to the picture with margins, keeping the aspect ratio.
//
// Rendering: 2 x 2 samples per pixel when the picture has at most 4 Mpixels (1 otherwise), averaged;
// triangles are rasterized conservatively (every sample whose square the triangle touches), so pipes and
// plates thinner than a sample still show. Memory: the sample buffers (14 bytes a sample) and one leaf.
//
// Thread safety: RenderLevel only reads `store`.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "engine/store_format/store_file.h"
#include "engine/viz/level_colouring.h"
#include "engine/viz/raster.h"
#include "mktree/status.h"

namespace mktree {

struct RenderOptions {
  int level = 0;  // k (>= 0)
  RenderView view = RenderView::kTop;
  uint32_t width = 1600;  // pixels, 64..16384
  uint32_t height = 400;  // pixels, 64..16384
  bool overlay = false;   // node boxes, overlap slabs and SplitTree cells at depth k
  // Optional: (leaves done, leaves total).
  std::function<void(uint64_t, uint64_t)> progress;
};

struct RenderReport {
  GroupCounts objects{};   // objects drawn per group (GroupIndex)
  uint64_t triangles = 0;  // triangles rasterized
  uint32_t samples_per_pixel = 1;
  double pixels_per_metre = 0;  // scale of the picture (scene units per pixel, inverted)
};

// Renders the level-`options.level` colouring of `store` and writes it as an 8-bit RGB PNG at `png_path`
// (temporary file and rename: nothing half-written on error).
Result<RenderReport> RenderLevel(const StoreReader& store, const std::string& png_path,
                                 const RenderOptions& options);

// Writes an 8-bit RGB image (rows top to bottom, 3 bytes a pixel) as a PNG, atomically.
Status WriteRgbPng(const std::string& path, uint32_t width, uint32_t height, const std::vector<uint8_t>& rgb);

}  // namespace mktree
