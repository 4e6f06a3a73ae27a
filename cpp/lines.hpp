// Lines and points: their setup (transform, clip, project, bin; once per render) and the tile
// overlay that draws them over a tile's resolved triangles, before the tile is written.
//
// Rules (the README states them):
//  - An endpoint or point is at pixel (floor(x_window), floor(y_window)), the window transform of
//    vertex.cpp in double (pixel (i, j) has its centre at (j + 0.5, i + 0.5)).
//  - width <= 1: one pixel per step along the major axis (|dx| >= |dy|: x), from the first
//    endpoint's pixel to the second's, both drawn. Bresenham (the integer all-octant loop): the
//    minor offset at step k is round(k |dm| / M), halves away from the first endpoint, i.e.
//    floor((2 k |dm| + M) / (2 M)). DDA: minor = floor(m0 + k dm / M + 0.5) in double (halves
//    toward +x / +y), each step evaluated afresh rather than accumulated.
//  - width > 1: every pixel whose centre lies within width / 2 of the projected segment (the
//    clipped endpoints' window positions, not their pixels: a capsule with round caps, whose
//    pixel count follows length x width; the line algorithm does not matter).
//  - A point of size s: pixels whose centre c has x - s/2 < c.x <= x + s/2 (and the same in y),
//    (x, y) the projected point; s < 1 draws as 1, so size 1 is the pixel holding the point.
//  - Segments are clipped to the near and far planes and the guard band in homogeneous space
//    (Liang-Barsky, double); a point outside them is dropped. Pixels outside the image are not
//    drawn (the visible part is the unclipped line's). Where the endpoints are so large next to
//    the visible part that the clip-space lerp would be off (by more than 2^-16 px), the segment
//    is clipped again relative to its point nearest the camera (lines.cpp, clip_far_segment):
//    a segment from x = -1e20 to 1e20 at depth 5 draws its visible part, not one pixel.
//  - Each pixel's attributes are those of the segment's point nearest the pixel centre in the
//    window (parameter s), perspective-correct: t = s / w_b / ((1 - s) / w_a + s / w_b); depth,
//    colour and world position are lerps by t.
//  - The overlay runs after the tile's triangles (after the resolve, with msaa / ssaa: lines and
//    points are aliased and cover whole pixels, alpha 1); a fragment wins where nothing is drawn
//    or where it is nearer than the pixel's key by the render's tie factor (rasterize.hpp), so
//    ties keep the triangles, then primitives in scene order.
#pragma once

#include "clip.hpp"
#include "pipeline.hpp"
#include "rasterize.hpp"
#include "thread_pool.hpp"
#include "transform.hpp"
#include "viewport.hpp"

#include <string>
#include <vector>

namespace sr {

enum class LineAlgorithm : uint8_t { Bresenham, Dda };

// A visibility-buffer entry for a pixel a line or point owns (write_tile reads its ids and
// surface from PrimitivePixels). Never a triangle index: a tile would need 2^32 - 1 of them.
constexpr uint32_t kPrimitivePixel = 0xfffffffeu;

// Widest line or point, pixels: with the guard band (|window| < 2^16) every pixel box fits int32.
constexpr float kMaxPrimitiveWidthPx = 1e6f;

// One Lines or Points object placed in the scene: views of arrays that the caller keeps alive and
// unchanged during the render (bindings.cpp: the spec holds them).
struct PrimitiveDraw {
  bool points = false;
  ConstSpan<vec3> positions;   // model space
  ConstSpan<glm::ivec2> segments;   // lines: endpoint indices into positions
  ConstSpan<vec3> colors;      // linear RGB per position; empty => `color`
  vec3 color{1.0f};
  float width = 1.0f;          // line width or point size, pixels, > 0
  dmat4 model{1.0};            // model -> world
  int32_t instance_id = 0;
  // Lines only: in the depth test a fragment counts as nearer by this fraction of its depth, in
  // [0, 1) (render(wireframe=True): edges over their own faces); its depth output is unbiased.
  float depth_bias = 0.0f;
};
// Throws std::invalid_argument naming the bad argument (`where` names the draw).
void validate_primitive(const PrimitiveDraw& draw, const std::string& where);

// A segment after clipping and projection.
struct LineRecord {
  double x[2], y[2];       // window coordinates of the clipped endpoints
  int32_t px[2], py[2];    // their pixels
  double inv_w[2];         // 1 / w_clip, the perspective-correct weights
  double depth[2];         // view depth (-z_view)
  vec3 color[2];           // linear
  vec3 world[2];
  float width;
  int32_t instance_id;
  float bias;              // the depth test compares key * bias (1: none; PrimitiveDraw::depth_bias)
};
// A point after projection: its pixel square (inclusive bounds, not clipped to the image).
struct PointRecord {
  int32_t x0, y0, x1, y1;
  float key;               // depth key (pipeline.hpp)
  vec3 color;
  vec3 world;
  int32_t instance_id;
};

// A point of size <= 1 (one pixel: the common point cloud) after projection: its pixel as an
// offset in its tile's rows (kTileSizePx wide), its depth key and its index in the draw. A third
// of a PointRecord: a million points' records are written, binned and read once per render, and
// the colour and position are read from the draw only for the pixels a point wins.
struct DotRecord {
  uint32_t pixel;
  float key;
  uint32_t index;
};

// The records of a block of one draw's primitives, binned, in primitive order within each tile:
// a tile t's lines are lines[tile_records[tile_begin[t] .. tile_begin[t + 1])]; its points are
// binned_dots[tile_begin[t] .. tile_begin[t + 1]) (copies, so a tile reads its points in one
// sequential run: a million points' records do not fit in cache, and fetching them by index
// missed it for every point).
// Points of size <= 1 are DotRecords instead: a tile's are binned_pixels[tile_begin[t] ..
// tile_begin[t + 1]), and the block keeps its draw to resolve them.
struct PrimitiveBlock {
  bool points = false;
  bool one_pixel = false;  // points of size <= 1: pixels / binned_pixels, not dots
  PrimitiveDraw draw;      // the block's draw (one_pixel: its colours, positions and pose)
  std::vector<LineRecord> lines;
  std::vector<PointRecord> dots, binned_dots;
  std::vector<DotRecord> pixels, binned_pixels;
  std::vector<uint32_t> tile_begin, tile_records;
  std::vector<uint32_t> single_tile;  // points: the one tile a point is binned to, or ~0u
};

// Every primitive of a render, set up; reused from render to render (capacity kept).
struct PrimitiveSetup {
  std::vector<PrimitiveBlock> blocks;
  std::size_t num_blocks = 0;
  std::vector<uint8_t> tile_used;  // per tile: some block binned a record to it
  LineAlgorithm algorithm = LineAlgorithm::Bresenham;
  bool orthographic = false;
  bool need_world = false;  // the position / ray_depth outputs

  // Transforms, clips, projects and bins `draws`, in parallel over blocks of primitives (the
  // result does not depend on the thread count).
  // `need_world`: the position or ray_depth output is requested (else records' world points are
  // left 0 and never read).
  void build(const std::vector<PrimitiveDraw>& draws, const CameraParams& camera,
             const Viewport& viewport, LineAlgorithm line_algorithm, bool need_world,
             ThreadPool& pool);
  bool any(int tile) const { return num_blocks > 0 && tile_used[std::size_t(tile)]; }
};

// What a primitive pixel holds beyond the tile buffers: the record that won it (its block, and
// its index in the block's lines or binned_dots, or a one-pixel point's index in its draw), its
// instance id and world position.
struct PrimitivePixels {
  uint32_t block[kTilePixels];
  uint32_t record[kTilePixels];
  int32_t instance[kTilePixels];
  float position[3][kTilePixels];
};

// The tile buffers the overlay reads and writes (row stride kTileSizePx, from the tile's
// top-left pixel): the resolved key and visibility buffer, shading's radiance and normal planes,
// and with anti-aliasing the resolved alpha and premultiplied radiance (else null).
struct OverlayTarget {
  float* key;
  uint32_t* visible;
  float* rgb[3];
  float* normal[3];
  float* alpha;
  float* radiance[3];
  float tie;
  PrimitivePixels* pixels;
};

// Draws every line and point binned to `tile` into `target`, in scene order.
void draw_primitives_tile(const PrimitiveSetup& setup, const TileRect& rect, int tile,
                          const OverlayTarget& target);

}  // namespace sr
