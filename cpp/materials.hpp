// Lights and materials as the core reads them: what a draw and a render carry (pipeline.hpp),
// apart from the formulas that use them (lighting.hpp). python/softrast/material.py and light.py
// state their meaning; bindings fill them by name.
#pragma once

#include "math.hpp"

#include <array>
#include <cstdint>
#include <memory>

namespace sr {

class Texture;
struct ShadowMap;  // shadow.hpp

enum class LightKind : uint8_t { Directional, Point, Spot };

// Whether a light casts shadows, and how (python/softrast/light.py; shadow.hpp states the rules).
enum class ShadowMethod : uint8_t { None, Exact, Map };

// One light in world space (python/softrast/light.py, Light._core).
struct Light {
  LightKind kind = LightKind::Directional;
  vec3 radiance{1.0f};     // colour * intensity
  vec3 position{0.0f};     // point and spot lights
  vec3 direction{0.0f, 0.0f, -1.0f};  // unit, the direction the light travels
  bool inverse_square = true;          // point and spot: radiance / r^2
  float cone_scale = 0.0f, cone_offset = 1.0f;  // spot: clamp(cos * scale + offset, 0, 1)^2
  ShadowMethod shadow = ShadowMethod::None;     // its diffuse and specular terms are shadowed
  std::shared_ptr<const ShadowMap> map;         // ShadowMethod::Map: its depth maps
};

// How a draw is shaded (a per-triangle choice, shade_models.hpp): a material's reflectance
// models and the debug views (render(shading=) names, in this order: bindings.cpp), then the
// headlight's Lambert, the plan's choice for a plain scene (renderer.cpp).
enum class Brdf : uint8_t { Unlit, Lambert, Phong, BlinnPhong, Pbr, Normal, Uv, Depth, Headlight };
// A material's models are the first six (the debug views Uv and Depth, and Headlight, only come
// from a render's options).
constexpr int kNumMaterialModels = int(Brdf::Normal) + 1;

// Where lighting is evaluated: per pixel (Phong shading), at the vertices with the colour
// interpolated (Gouraud), or once per face with its face normal (flat).
enum class Frequency : uint8_t { Pixel, Vertex, Face };

// A material as the core reads it (python/softrast/material.py). ka / kd follow the base colour
// (vertex colours, else the draw's colour) where the flags say so. A draw without a material has
// the default one: Lambert of its base colour, two-sided (plain()).
struct Material {
  Brdf model = Brdf::Lambert;  // its reflectance model (render(shading="auto") draws it so)
  bool kd_is_base = true;   // kd = the base colour
  bool ka_is_kd = true;     // ka = kd
  bool double_sided = true;
  vec3 ka{0.0f}, kd{0.0f}, ks{0.0f};
  float shininess = 32.0f;
  float metallic = 0.0f, roughness = 0.5f;
  vec3 emissive{0.0f};   // zero where an emissive texture carries it (emissive_factor)
  // Textures (texture.hpp), null where absent; the lit model samples them per pixel.
  const Texture* base_color_texture = nullptr;  // multiplies the base colour (rgb)
  const Texture* emissive_texture = nullptr;    // emissive_factor * its rgb is added
  const Texture* normal_texture = nullptr;      // tangent space, OpenGL-style unless normal_y_down
  const Texture* metallic_roughness_texture = nullptr;  // glTF: green * roughness, blue * metallic
  const Texture* occlusion_texture = nullptr;   // red: ambient *= 1 + strength (red - 1)
  const Texture* bump_texture = nullptr;        // a height map (first channel), bump_scale
  const Texture* specular_texture = nullptr;    // rgb scales ks (phong, blinn_phong; MTL map_Ks)
  vec3 emissive_factor{0.0f};
  float normal_scale = 1.0f;
  float occlusion_strength = 1.0f;
  float bump_scale = 1.0f;
  bool normal_y_down = false;  // DirectX-style normal map (green = -v)
  bool alpha_mask = false;     // glTF alphaMode MASK: fragments with alpha < alpha_cutoff are
  float alpha_cutoff = 0.5f;   // discarded (alpha_mask.hpp); else the draw is opaque
  bool alpha_blend = false;    // glTF alphaMode BLEND: composited over what lies behind it in
                               // depth order (blend.hpp); never together with alpha_mask
  // Every texture slot, null where absent (the one list of them).
  std::array<const Texture*, 7> textures() const {
    return {base_color_texture, emissive_texture, normal_texture, metallic_roughness_texture,
            occlusion_texture, bump_texture, specular_texture};
  }
  bool textured() const {
    for (const Texture* t : textures())
      if (t) return true;
    return false;
  }
  // Per-pixel material values (MaterialLanes) replace the scalar ones.
  bool material_maps() const {
    return metallic_roughness_texture || occlusion_texture || specular_texture;
  }
  // Lambert of the base colour, two-sided, opaque: a scene of plain Lambert draws without lights
  // gets the headlight's kernel (renderer.cpp, the plan).
  bool plain() const {
    return kd_is_base && ka_is_kd && emissive == vec3(0.0f) && double_sided && !textured() &&
           !alpha_mask && !alpha_blend;
  }
};

}  // namespace sr
