// Transform stage: the matrices of a draw (the per-vertex work is transform_point, inline).
#include "transform.hpp"

#include <cmath>

namespace sr {

DrawTransform make_draw_transform(const dmat4& model, const CameraParams& camera) {
  DrawTransform xf;
  const dmat4 model_view = camera.view * model;  // double: large translations cancel here
  xf.model_view = mat4(model_view);
  xf.proj = mat4(camera.proj);
  const dmat3 m3(model);
  const double det = glm::determinant(m3);
  xf.mirrored = det < 0.0;
  // A mirroring model matrix turns counter-clockwise faces clockwise; like most engines we flip
  // the facing test with it, so the outside of a mirrored closed mesh stays its front.
  xf.normal_to_world = glm::inverseTranspose(m3);
  return xf;
}

}  // namespace sr
