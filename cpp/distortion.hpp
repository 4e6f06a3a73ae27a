// Lens distortion's per-pixel work (the method: python/softrast/distortion.py). A distorted
// camera is rendered as an oversampled ideal pinhole view; each output pixel then resolves, on its
// own ray, which of the view's nearby triangles it sees, and takes colours by bilinear weights.
#pragma once

#include "math.hpp"
#include "pipeline.hpp"

#include <cstdint>
#include <vector>

namespace sr {

// The output pixels' rays and where each falls in the ideal view (row-major, n = width * height).
struct DistortionRays {
  int64_t n = 0;
  int64_t view_width = 0, view_size = 0;  // the ideal view's width and pixel count
  const uint8_t* valid = nullptr;         // the lens model has a ray for this pixel
  const int64_t* nearest = nullptr;       // the view sample nearest the ray's point
  const int64_t* corner = nullptr;        // top-left of the 2x2 around it (bilinear's)
  const double* directions = nullptr;     // (n, 3): (x', y', 1) in OpenCV camera axes
  double sample_to_normalized[4] = {};    // view sample (i, j) -> x' = j a + b, y' = i c + d
};

// One instance as the ideal view drew it: the view's instance_id output holds its index.
struct RayInstance {
  const MeshData* mesh = nullptr;
  dmat4 model{1.0};  // model -> world
  // Set by resolve_distorted: the inverse of model's 3x3 (0 if singular) and the camera centre
  // in model space.
  dmat3 inverse_linear{1.0};
  dvec3 origin{0.0};
};

// Per output pixel: the view sample whose outputs it takes (the nearest one where nothing covers
// it) and, where covered, its surface point. `depth` .. `barycentric` may be null (not wanted).
struct DistortionHits {
  int64_t* sample = nullptr;
  uint8_t* covered = nullptr;
  double* depth = nullptr;        // along the viewing axis
  double* ray_depth = nullptr;    // from the camera centre
  double* position = nullptr;     // (n, 3) world
  double* barycentric = nullptr;  // (n, 3) of the face's corners in order
};

// camera_to_world: OpenCV camera axes to world (its columns), centre: the camera centre. The
// triangle and instance ids are the view's outputs (-1 = background). On `threads` threads
// (each writes its own pixels: the same bits for any count). Throws std::invalid_argument for
// an id that names no instance or face.
void resolve_distorted(const DistortionRays& rays, const int32_t* triangle_id, const int32_t* instance,
                       std::vector<RayInstance> instances, const dmat3& camera_to_world,
                       const dvec3& centre, const DistortionHits& hits, int threads);

// out[p] = (s[c] w0 + s[c + 1] w1) + (s[c + W] w2 + s[c + W + 1] w3) per channel, c = corner[p],
// in float32; for uint8 rounded half up. Pixels without a ray are left alone.
void bilinear_gather(const DistortionRays& rays, const float* weights /* (4, n) */, const uint8_t* src,
                     int channels, uint8_t* out);
void bilinear_gather(const DistortionRays& rays, const float* weights, const float* src, int channels,
                     float* out);

}  // namespace sr
