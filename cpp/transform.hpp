// Transform stage: model -> world -> view -> clip, per vertex; normals by the inverse-transpose.
#pragma once

#include "pipeline.hpp"

namespace sr {

// Matrices of one draw, composed in double precision so a mesh far from the origin but near the
// camera keeps its precision, then rounded once to float for the per-vertex work.
struct DrawTransform {
  mat4 model_view;         // model -> view
  mat4 proj;               // view -> clip
  dmat4 model_view_d;      // the same in double, for the points clipping creates (clip.cpp)
  dmat4 proj_d;
  dmat4 model_view_proj_d;  // proj_d * model_view_d: the exact window positions and keys (vertex.cpp)
  bool w_is_depth = false;  // its w row is the negated view z row, bit for bit (a perspective
                            // projection's (0, 0, -1, 0)): exact_clip's w and depth are equal
  dmat3 normal_to_world;   // inverse-transpose of the model's 3x3 (double: normals may be huge),
                           // its cofactor matrix where that does not exist (transform.cpp);
                           // times a power of two: largest |entry| in [1, 2) (a direction only)
  bool mirrored = false;   // det(model) < 0: the winding flips, so front/back facing swap too
};

DrawTransform make_draw_transform(const dmat4& model, const CameraParams& camera);

// Clip-space position and view depth of one model-space point. Written out because GLM's
// mat4 * vec4 is not inlined; the sums are grouped as GLM groups them, (c0 x + c1 y) + (c2 z + c3 w).
// The vertex pass and the clipping path both call this, so a vertex recomputed for clipping has
// exactly the bits the vertex pass classified.
[[gnu::always_inline]] inline ClipVertex transform_point(const DrawTransform& xf, const vec3& p) {
  const mat4& m = xf.model_view;
  const mat4& c = xf.proj;
  float v[4];
  for (int r = 0; r < 4; ++r)  // the model-space point's w is 1: m[3][r] * 1 is m[3][r]
    v[r] = (m[0][r] * p.x + m[1][r] * p.y) + (m[2][r] * p.z + m[3][r]);
  ClipVertex out;
  for (int r = 0; r < 4; ++r)
    out.p_clip[r] = (c[0][r] * v[0] + c[1][r] * v[1]) + (c[2][r] * v[2] + c[3][r] * v[3]);
  out.depth_view = -v[2];
  return out;
}

// The same point in double (clip.cpp: where clipping cuts an edge, its endpoints' float rounding
// would be magnified: a ground plane 1e6 units wide cut at a near plane 0.05 from the camera).
struct ClipVertexD {
  dvec4 p_clip;
  double depth_view;
};
inline ClipVertexD transform_point_d(const DrawTransform& xf, const vec3& p) {
  const dvec4 v = xf.model_view_d * dvec4(double(p.x), double(p.y), double(p.z), 1.0);
  return {xf.proj_d * v, -v.z};
}

// A point's clip x, y, w and view depth in double, for the window position's unsnapped residual
// and the depth key (vertex.cpp, project): where the float32 transform's rounding (2^-24 of a
// coordinate) would tilt a steep depth plane by many units in its last place. Each as
// (c0 x + c1 y) + (c2 z + c3), the order of the vertex pass's lanes, so the same bits.
struct ExactClip {
  double x, y, w, depth;
};
inline double exact_row(const dmat4& a, int r, double x, double y, double z) {
  return (a[0][r] * x + a[1][r] * y) + (a[2][r] * z + a[3][r]);
}
inline ExactClip exact_clip(const DrawTransform& xf, const vec3& p) {
  const double x = p.x, y = p.y, z = p.z;
  const dmat4& c = xf.model_view_proj_d;
  return {exact_row(c, 0, x, y, z), exact_row(c, 1, x, y, z), exact_row(c, 3, x, y, z),
          -exact_row(xf.model_view_d, 2, x, y, z)};
}

}  // namespace sr
