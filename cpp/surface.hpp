// The exact surface step: a pixel's (or sample's) own ray, in double, intersected with the plane
// of its visible triangle's unsnapped corners. The raster decides which triangle is visible (on
// the snapped triangle: watertight, exact coverage); this step decides where on it the pixel's
// ray lands, so depth, ray_depth, position, barycentric and uv do not inherit the 1/512 px snap,
// which along a grazing ray is a large shift in depth (README, "Surface outputs are exact").
#pragma once

#include "math.hpp"

#include <cstdint>

namespace sr {

// The camera's rays in view space, affine in window coordinates (x, y), pixel (i, j)'s centre at
// (j + 0.5, i + 0.5): the ray through (x, y) is origin(x, y) + t direction(x, y). Perspective:
// the origin is the camera centre (0) and the direction (a point of the near plane, times its
// homogeneous w) has a free scale and sign; orthographic: the origin is the point on the near
// plane and the direction the (constant) viewing axis.
struct ViewRays {
  dvec3 d0{0.0}, dx{0.0}, dy{0.0};  // direction(x, y) = d0 + x dx + y dy
  dvec3 o0{0.0}, ox{0.0}, oy{0.0};  // origin(x, y) = o0 + x ox + y oy
  bool orthographic = false;
};
ViewRays make_view_rays(const dmat4& proj, int width, int height, bool orthographic);

// One visible face's plane in view space, from its three corners posed in double.
struct ExactTriangle {
  dvec3 v0{0.0}, e1{0.0}, e2{0.0};  // corner 0 and the edges to corners 1 and 2
  dvec3 n{0.0};                     // e1 x e2
  double h = 0.0;                   // the plane: n . v = h
  double inv_nn = 0.0;              // 1 / (n . n), 0 for a degenerate face
};
ExactTriangle exact_triangle(const dmat4& model_view, const vec3& c0, const vec3& c1,
                             const vec3& c2);

// Where the ray through window point (x, y) meets the triangle's plane. False when it does not
// (a degenerate face, a ray parallel to the plane, a non-finite point, or, for a perspective
// camera, a point not in front of the camera): the caller keeps the raster's own values there.
struct ExactHit {
  dvec3 view;       // the point, in view space
  double bary[3];   // of the face's corners (may lie slightly outside [0, 1]: the raster's
                    // snapped triangle can cover a pixel centre just outside the true one)
};
bool exact_hit(const ViewRays& rays, const ExactTriangle& tri, double x, double y, ExactHit& hit);

// The view depth of the hit only (depth output; the same point as exact_hit's).
bool exact_depth(const ViewRays& rays, const ExactTriangle& tri, double x, double y, double& depth);

}  // namespace sr
