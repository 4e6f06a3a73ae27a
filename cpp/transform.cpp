// Transform stage: the matrices of a draw (the per-vertex work is transform_point, inline).
#include "transform.hpp"

#include <algorithm>
#include <cmath>

namespace sr {

namespace {

// A normal matrix the shading can use: finite and not zero. glm::inverseTranspose divides the
// cofactor matrix by the determinant, so it is not when that is 0 (a pose with zero scale on an
// axis: inf and 0/0 = NaN entries, which gave zero normals and ambient-only shading) or when it
// over- or underflows double (a uniform scale of 1e110: det 1e330 = inf, every entry 1e220 / inf
// = 0; 1e200: inf / inf = NaN).
bool usable_normal_matrix(const dmat3& m) {
  bool nonzero = false;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) {
      if (!std::isfinite(m[c][r])) return false;
      nonzero |= m[c][r] != 0.0;
    }
  return nonzero;
}

// m scaled to a largest entry of 1 (zero if m is zero): a positive factor, which changes no
// normal's direction nor the sign of the determinant, and brings 1e-200 and 1e200 scales back
// inside double's range.
dmat3 unit_scaled(const dmat3& m) {
  double largest = 0.0;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) largest = std::max(largest, std::fabs(m[c][r]));
  return largest > 0.0 ? m * (1.0 / largest) : dmat3(0.0);
}

// The cofactor matrix of a: adj(a)^T = det(a) * inverse(a)^T, but defined for singular matrices.
// It maps a face normal u x v to (a u) x (a v), the normal of the transformed face: a sphere
// flattened onto z = 0 gets normals +-z, right for the flat disc it has become. A face the pose
// collapses to a segment or a point gets a zero normal, and so does every face under a pose of
// rank <= 1 (the cofactor matrix is 0); such faces are degenerate on screen too, and a zero normal
// is written as 0 and shades as ambient only, never NaN (unit() in shade.cpp).
dmat3 cofactor_matrix(const dmat3& a) {
  dmat3 cof;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) {
      const int c1 = (c + 1) % 3, c2 = (c + 2) % 3, r1 = (r + 1) % 3, r2 = (r + 2) % 3;
      cof[c][r] = a[c1][r1] * a[c2][r2] - a[c1][r2] * a[c2][r1];
    }
  return cof;
}

// m times a power of two that brings its largest |entry| into [1, 2) (m unchanged if zero). Only
// the direction of normal_to_world * n is ever used, and a power of two scales exactly: the same
// unit normals, bit for bit, for every pose whose products stay in double's normal range (a
// rotation, or any pose of scale 1e-30..1e30: the factor is 1 for a largest entry in [1, 2)), and
// no overflow where they would not (a pose scaling an axis by 1e-160: entries 1e160, on face
// normals up to 1e78, squared 1e476).
dmat3 power_of_two_scaled(const dmat3& m) {
  double largest = 0.0;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) largest = std::max(largest, std::fabs(m[c][r]));
  if (!(largest > 0.0) || !std::isfinite(largest)) return m;
  const int e = std::ilogb(largest);
  if (e == 0) return m;
  dmat3 out;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) out[c][r] = std::ldexp(m[c][r], -e);
  return out;
}

}  // namespace

DrawTransform make_draw_transform(const dmat4& model, const CameraParams& camera) {
  DrawTransform xf;
  const dmat4 model_view = camera.view * model;  // double: large translations cancel here
  xf.model_view = mat4(model_view);
  xf.proj = mat4(camera.proj);
  xf.model_view_d = model_view;
  xf.proj_d = camera.proj;
  xf.model_view_proj_d = camera.proj * model_view;
  xf.w_is_depth = true;
  for (int c = 0; c < 4; ++c) xf.w_is_depth &= xf.model_view_proj_d[c][3] == -model_view[c][2];
  const dmat3 m3(model);
  double det = glm::determinant(m3);
  // 0 in double can be an underflow (a mirror scaled by 1e-120: det -1e-360); the scaled
  // matrix has the true sign, and an exactly singular pose keeps det 0 (not mirrored).
  if (det == 0.0) det = glm::determinant(unit_scaled(m3));
  xf.mirrored = det < 0.0;
  // A mirroring model matrix turns counter-clockwise faces clockwise; like most engines we flip
  // the facing test with it, so the outside of a mirrored closed mesh stays its front.
  xf.normal_to_world = glm::inverseTranspose(m3);
  if (!usable_normal_matrix(xf.normal_to_world)) {
    // The cofactor matrix is det(m) * inverse(m)^T: negated for a mirror, it points where the
    // inverse-transpose does, so normals agree with the facing test that `mirrored` flips.
    xf.normal_to_world = cofactor_matrix(unit_scaled(m3));
    if (xf.mirrored) xf.normal_to_world = -xf.normal_to_world;
  }
  xf.normal_to_world = power_of_two_scaled(xf.normal_to_world);
  return xf;
}

}  // namespace sr
