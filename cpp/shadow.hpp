// Exact shadows (Light::shadow == ShadowMethod::Exact): whether a shaded point sees a light,
// decided by a ray from the point to the light against every occluding triangle, in double.
//
// The rule (python/softrast/light.py states it for users):
//   - the ray leaves the shaded point p toward the light: along -direction for a directional
//     light (any distance), toward the position of a point or spot light (only blockers between
//     p and the light count: 0 < t < 1 with d = light - p);
//   - a triangle blocks where the ray meets it (Moller-Trumbore in double, edges included);
//   - a triangle whose plane passes within eps of p never blocks it, eps = 2^-19 times the
//     largest coordinate magnitude of its corners and of p: p is a float32 point of the surface
//     it lies on (its interpolation error is a few float32 ulps of that surface's coordinates),
//     and a surface through the shaded point does not shadow it. This replaces a shadow bias: it
//     is not a distance along the ray, is the same for every scene, and gives no acne at any
//     angle (a floor under an 89.9 degree light is lit everywhere);
//   - the occluders are every triangle of every draw that is drawn opaque or masked (masked by
//     geometry: the alpha test is not applied to shadow rays), both faces, in the view or not;
//     blended and invisible draws cast none.
// A shadowed light's diffuse and specular terms are multiplied by the visibility (0 or 1), in
// every lit model, at the point where the render's frequency evaluates the light (each pixel,
// each vertex, each face's centre); ambient and emissive light are not shadowed.
//
// The occluders sit in a bounding volume hierarchy (binned surface-area heuristic, at most four
// triangles a leaf) built once per render that has a shadowed light; a ray stops at its first
// blocker. Scalar and compiled once for the generic target: both instruction sets' kernels get
// the same decisions.
#pragma once

#include "materials.hpp"
#include "math.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace sr {

struct Draw;

class ShadowScene {
 public:
  // The occluders: every triangle of each draw d with casts[d], posed in double by its model
  // matrix. Triangles of zero area (or not finite) are left out: no ray meets them.
  void build(const std::vector<Draw>& draws, const std::vector<uint8_t>& casts);
  // Whether an occluder blocks the ray from p toward `light` (the rule above).
  bool blocked(const Light& light, const dvec3& p) const;
  std::size_t size() const { return tris_.size(); }

 private:
  struct Tri { dvec3 a, e1, e2; };  // corners a, a + e1, a + e2
  // A leaf holds triangles [index, index + count); an inner node (count 0) has its children at
  // this + 1 and at `index`.
  struct Node { dvec3 lo, hi; uint32_t index, count; };
  bool hits(const Tri& tri, const dvec3& o, const dvec3& d, double t_max) const;
  std::vector<Node> nodes_;
  std::vector<Tri> tris_;
};

// The visibility (1 or 0) of each light at the points (x[i], y[i], z[i]) of the lanes set in
// `mask` (bit i: lane i), at [8 k + i] for light k, in a buffer of the calling thread (valid
// until its next call). 1 for lights without shadows, in the other lanes, at points that are not
// finite, and, given normals (nx, ny, nz; else null), where the normal faces away from the light
// (n . (to the light) < -2^-20 |n| |to the light|: such a lane adds nothing from that light in
// the models that pass normals). Arrays cross the call (callers are compiled for AVX2 or not).
const float* shadow_lights(const ShadowScene& scene, const Light* lights, int num_lights,
                           const float* x, const float* y, const float* z, const float* nx,
                           const float* ny, const float* nz, uint32_t mask);

}  // namespace sr
