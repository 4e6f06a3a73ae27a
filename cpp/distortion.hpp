// Lens distortion's per-pixel work (the method: python/softrast/distortion.py). Every output
// pixel casts its own float64 ray at every triangle whose footprint can reach it (cast_distorted:
// the rays bucketed in a grid of the ideal image plane, each triangle's clipped box scattered
// over it); colours come from an oversampled ideal pinhole view by bilinear weights.
#pragma once

#include "alpha_mask.hpp"
#include "math.hpp"
#include "pipeline.hpp"

#include <cstdint>
#include <vector>

namespace sr {

// The output pixels' rays and where each falls in the ideal view (row-major, n = width * height):
// the bilinear gathers' and the masked draws' view samples.
struct DistortionRays {
  int64_t n = 0;
  int64_t view_width = 0, view_size = 0;  // the ideal view's width and pixel count
  const uint8_t* valid = nullptr;         // the lens model has a ray for this pixel
  const int64_t* nearest = nullptr;       // the view sample nearest the ray's point
  const int64_t* corner = nullptr;        // top-left of the 2x2 around it (bilinear's)
};

// Each output pixel's ray (x', y', 1) in OpenCV camera axes, bucketed by where it meets the
// ideal image plane z = 1: cell (i, j) holds the rays with x' in x0 + [j, j + 1) / inv_cell_x and
// y' in y0 + [i, i + 1) / inv_cell_y. Rays are stored in cell order (rows of cells, then columns),
// so the rays of cells j0..j1 of one row are one contiguous range.
struct RayGrid {
  int64_t n = 0;                        // output pixels
  int64_t count = 0;                    // rays: the pixels the lens model reaches
  const int64_t* pixel = nullptr;       // (count) each ray's output pixel
  const double* xy = nullptr;           // (count, 2) each ray's x', y'
  const int64_t* slot = nullptr;        // (n) each pixel's ray (its index in cell order), -1: none
  const int64_t* cell_start = nullptr;  // (nx * ny + 1) cell c's rays: [cell_start[c], cell_start[c + 1])
  int64_t nx = 0, ny = 0;
  double x0 = 0.0, y0 = 0.0, inv_cell_x = 1.0, inv_cell_y = 1.0;
};

// One instance as the render sees it; its index in the list is the instance_id the outputs report.
struct CastDraw {
  const MeshData* mesh = nullptr;
  dmat4 model{1.0};  // model -> world
  Cull cull = Cull::Back;  // the render's, or None for a double-sided material's draw
  // Opaque: cast at exactly; Masked (an alpha test): hit only where the ideal view's samples
  // around the ray show its triangle (their alpha test decides); Invisible: never hit.
  AlphaKind alpha = AlphaKind::Opaque;
};

struct CastCamera {
  dmat3 camera_to_world{1.0};  // OpenCV camera axes -> world (columns)
  dvec3 centre{0.0};
  double near = 0.05, far = 100.0;  // the depth range a point must lie in (along the +z axis)
};

// The ideal view's ids (its instance_id output = the index of the CastDraw), for masked draws
// and for `sample`; null where no view was rendered.
struct CastView {
  const DistortionRays* rays = nullptr;
  const int32_t* triangle_id = nullptr;
  const int32_t* instance = nullptr;
};

// Per output pixel, each optional (null: not wanted); background where nothing is hit or the pixel
// has no ray: -1 for the ids and `sample`'s nearest sample... (see sample), 0 otherwise.
struct CastOutputs {
  int32_t* triangle_id = nullptr;
  int32_t* instance = nullptr;    // the CastDraw's index
  uint8_t* mask = nullptr;
  float* depth = nullptr;         // along the viewing axis
  float* ray_depth = nullptr;     // from the camera centre
  float* position = nullptr;      // (n, 3) world
  float* barycentric = nullptr;   // (n, 3) of the face's corners in order
  float* uv = nullptr;            // (n, 2)
  float* normal = nullptr;        // (n, 3) world, unit, of the side the ray sees (interpolated)
  uint32_t* coverage = nullptr;   // the triangles the ray hits (culling applied), before the nearest
  float* alpha = nullptr;         // 1 where hit
  // The view sample whose shaded values stand for the hit: the first of the nearest sample and
  // the four around the ray's point that shows the hit triangle, else the nearest (needs a view).
  int64_t* sample = nullptr;
};

// The nearest hit along each pixel's ray among every triangle of `draws` (culling as the pinhole
// render culls: a face is front facing where the camera centre sees its counter-clockwise side,
// flipped under a mirroring pose), with depth in [near, far]; ties to the first triangle in draw
// and face order. On `threads` threads; every pixel's result is independent of the thread count
// (each ray is owned by one thread, which sees the triangles in order): the same bits for any
// count. Throws std::invalid_argument for a view id that names no draw or face.
void cast_distorted(const RayGrid& grid, const std::vector<CastDraw>& draws, const CastCamera& camera,
                    const CastView& view, const CastOutputs& out, int threads);

// out[p] = (s[c] w0 + s[c + 1] w1) + (s[c + W] w2 + s[c + W + 1] w3) per channel, c = corner[p],
// in float32; for uint8 rounded half up. Pixels without a ray are left alone.
void bilinear_gather(const DistortionRays& rays, const float* weights /* (4, n) */, const uint8_t* src,
                     int channels, uint8_t* out);
void bilinear_gather(const DistortionRays& rays, const float* weights, const float* src, int channels,
                     float* out);

}  // namespace sr
