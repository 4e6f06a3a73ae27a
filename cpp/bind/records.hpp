// The records bindings make from Python's (records.cpp): what a render reads of each.
#pragma once

#include "bind.hpp"

#include "../lines.hpp"
#include "../texture.hpp"

#include <memory>

namespace sr {
namespace bind {

// A material and the textures it samples (kept alive with it).
struct MaterialRecord {
  enum Slot {
    k_base_color_texture, k_emissive_texture, k_normal_texture, k_metallic_roughness_texture,
    k_occlusion_texture, k_bump_texture, k_specular_texture, kSlots
  };
  Material material;
  vec3 emissive{0.0f};  // as given (resolved() moves it to the emissive texture's factor)
  std::shared_ptr<Texture> textures[kSlots];
  Material resolved() const;  // the material a render reads
};

// One mesh instance.
struct DrawRecord {
  std::shared_ptr<MeshData> mesh;
  dmat4 pose{1.0};
  int32_t instance_id = 0;
  vec4 color{0.8f, 0.8f, 0.8f, 1.0f};
  std::shared_ptr<MaterialRecord> material;  // null: the default material
  Draw draw() const;
};

// Lines or points, and the arrays they view.
struct PrimitiveRecord {
  PrimitiveDraw draw;
  py::object positions = py::none(), segments = py::none(), colors = py::none();
};

}  // namespace bind
}  // namespace sr
