// Shade stage: resolve each tile's visibility buffer into the requested outputs.
#pragma once

#include "framebuffer.hpp"
#include "rasterize.hpp"

namespace sr {

// What shading needs of one draw.
struct ShadeDraw {
  const MeshData* mesh;
  mat3 normal_to_world;  // inverse-transpose of the model matrix
  vec4 color;            // material colour (used when the mesh has no vertex colours)
  int32_t instance_id;
};

struct ShadeParams {
  const ShadeDraw* draws;
  Shading shading;
  vec3 to_light_world;  // unit vector toward the headlight (= toward the camera)
  float ambient;
  uint8_t background[3];
  bool orthographic;
  Framebuffer* framebuffer;
};

// Writes every pixel of `tile` in each requested output. Each visible pixel is shaded once.
void shade_tile(const ShadeParams& params, const Viewport& viewport, int tile,
                const TileScratch& scratch);

}  // namespace sr
