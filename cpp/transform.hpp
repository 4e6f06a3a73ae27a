// Transform stage: model -> world -> view -> clip, per vertex; normals by the inverse-transpose.
#pragma once

#include "pipeline.hpp"

namespace sr {

// Matrices of one draw, composed in double precision so a mesh far from the origin but near the
// camera keeps its precision, then rounded once to float for the per-vertex work.
struct DrawTransform {
  mat4 model_view;         // model -> view
  mat4 proj;               // view -> clip
  dmat3 normal_to_world;   // inverse-transpose of the model's 3x3 (double: normals may be huge)
  bool mirrored = false;   // det(model) < 0: the winding flips, so front/back facing swap too
};

DrawTransform make_draw_transform(const dmat4& model, const CameraParams& camera);

// Transforms positions[begin, end) into clip space: out[0 .. end - begin).
void transform_vertices(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                        std::size_t end, ClipVertex* out);

}  // namespace sr
