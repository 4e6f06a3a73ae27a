// Shading models as policies: what a model prepares once per visible triangle, and how it shades
// eight pixels at a time. The shading kernels (shade.cpp) are templates over the model, so a
// model's choices are made at compile time and what it does not read is never interpolated.
//
// A model is a struct with:
//   kId, kName     its Shading value and its public name (render(shading=kName))
//   kReadsNormal   colour depends on the surface normal: normals are prepared and interpolated
//   kReadsColor    colour depends on the base colour (vertex colours or the material colour)
//   kReadsPosition colour depends on the world-space position (point lights, ...)
//   kAttributes    floats per vertex it reads from the mesh's attribute array (its uvs, two
//                  floats, are the only one so far; 0: none)
//   kAttributesIfTextured  it reads them only for a draw whose material has textures (and sets
//                  the kReadUv bits in classify); else for every triangle
//   kUniformLit    it has a fast path for a triangle of one base colour whose normals vary
//                  (ShadeTriangle::kUniformLit, shade_uniform below)
//   Triangle       its per-triangle values, computed by classify()
//   Constants      its per-triangle values splatted to eight lanes
//   kFaceNormal    it may read the triangle's face normal (ShadeTriangle::face_normal, set by
//                  prepare() when the render's frequency is "face")
//   classify(in, uniform_color, s)  picks s.color_kind; for kConstantColor sets s.rgb; may
//                  clear bits of s.reads (what a varying-colour triangle interpolates)
//   shade(c, f, r, g, b)  a varying-colour pixel: base colour r, g, b (when kReadsColor) and the
//                  Fragment f (what the flags ask for) in, linear radiance out
//   shade_uniform(c, s, b0, b1, b2) (kUniformLit only) the factor the base colour is multiplied
//                  by, from the unnormalised perspective weights b_k
//   kDefersLight   (optional, false if absent) some triangles' lighting is left to a pass over
//                  the tile's full groups of pixels (shade_kernels.hpp, light_tile): then
//                  Constants::code is nonzero for them (ShadeScratch::lit_code), and
//                  surface(c, f, n, r, g, b) gives what that pass reads in place of shade()
// Give it a Shading value (pipeline.hpp) and list it in ShadingModels below: the dispatch
// compiles kernels for every listed model, and bindings.cpp exports the names to Python
// (softrast's render(shading=) and the CLI) from the list (ARCHITECTURE.md, "Add a shading model").
#pragma once

#include "lighting.hpp"
#include "pipeline.hpp"
#include "simd.hpp"
#include "texture.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <type_traits>

namespace sr {

// Per-render values every model may read.
struct ShadeInputs {
  vec3 to_light_world;  // unit vector toward the headlight (= toward the camera)
  float ambient;        // Lambert: ambient + (1 - ambient) * max(0, n . l)
  LitInputs lit;        // the lit model: lights, ambient light, eye
  Frequency frequency = Frequency::Pixel;
  uint8_t texture_filter = kNoFilterOverride;  // a TextureFilter for every texture, or each its own
};

// std::clamp(v, 0, 1) * 255 + 0.5 truncated.
// (NaN gives 0.)
inline uint32_t to_unorm8(float v) {
  v = v > 0.0f ? v : 0.0f;
  return uint32_t((v < 1.0f ? v : 1.0f) * 255.0f + 0.5f);
}
inline uint32_t pack_rgb(vec3 c) {
  return to_unorm8(c.x) | to_unorm8(c.y) << 8 | to_unorm8(c.z) << 16;
}

// std::clamp(v, 0, 1) * 255 + 0.5 truncated, per lane, as to_unorm8 does.
SR_INLINE simd::i8 to_unorm8(simd::f8 v) {
  const simd::f8 zero = simd::splat(0.0f), one = simd::splat(1.0f);
  const simd::f8 c0 = zero < v ? v : zero;  // NaN -> 0
  const simd::f8 c = c0 < one ? c0 : one;
  return __builtin_convertvector(c * 255.0f + 0.5f, simd::i8);
}

// A triangle visible in the tile being shaded, prepared once for all its pixels (shade.cpp,
// prepare). What varies across it picks the work per pixel; each output is decided on its own,
// so an output's bits do not depend on which other outputs were requested:
//   colour  kConstantColor  every pixel has one colour, precomputed (s.rgb);
//           kUniformLit     one base colour, normals varying: the model's shade_uniform;
//           kVaryingColor   normalised weights, what the model reads interpolated, then shade;
//   normal  one_normal: the precomputed unit normal, else the normalised interpolated normal.
struct ShadeTriangleBase {
  enum ColorKind : uint8_t { kVaryingColor, kUniformLit, kConstantColor };
  // Bits of `reads`: kReadUv interpolates the attributes, kReadUvDerivs also their screen
  // derivatives (d/dx, d/dy per pixel, exact from the triangle's plane equations).
  enum Reads : uint8_t { kReadNormal = 1, kReadPosition = 2, kReadUv = 4, kReadUvDerivs = 8 };
  float persp[3];   // 1 / (w_k * area2) / max_k(1 / w_k): E_k * persp[k] ~ perspective-correct
                    // weight, scaled so that the largest is about 1 (no float underflow)
  vec3 normal[3];   // world-space normal at each vertex (the face normal if flat), facing the
                    // camera's side for back faces; zero unless normals are read
  vec3 color[3];    // base colour at each vertex (only color[0] set where all are equal)
  ColorKind color_kind;
  bool uniform_color;  // the lit model's: the three colours are equal, read as is (unset for
                       // the others, which classify such a triangle as constant or uniformly lit)
  bool one_normal;     // the three normals are equal
  bool back_facing;    // the camera sees the triangle's back (normals are flipped to face it)
  uint8_t reads;       // kVaryingColor: what the model's shade reads beyond the base colour
                       // (Reads bits; the model's flags unless classify() clears some)
  vec3 rgb;            // kConstantColor: the linear radiance of every pixel
  vec3 unit_normal;    // one_normal: the unit normal of every pixel (zero if the normal is zero)
  const Material* material;  // the draw's
  uint32_t draw;             // its index
};
template <typename Model>
struct ShadeTriangle : ShadeTriangleBase {
  typename Model::Triangle model;
  vec3 position[Model::kReadsPosition ? 3 : 1];  // world space at each vertex (kReadsPosition)
  vec3 face_normal;  // kFaceNormal and frequency "face": the unit face normal, visible side
  float attr[3][Model::kAttributes > 0 ? Model::kAttributes : 1];  // at each vertex (kAttributes)
  // kReadUvDerivs: the x and y derivatives of the unnormalised weights' sum S = sum_k b_k and of
  // sum_k b_k attr_k; an attribute's derivative is then (A_x - attr * S_x) / S at each pixel.
  float sum_dx, sum_dy;
  float attr_dx[Model::kAttributes > 0 ? Model::kAttributes : 1];
  float attr_dy[Model::kAttributes > 0 ? Model::kAttributes : 1];
};

// What a model reads at eight pixels, interpolated with perspective-correct weights. Only what
// its flags ask for is computed; the rest is left unset.
template <typename Model>
struct Fragment {
  simd::f8 normal[3];    // world-space unit normal of the visible side (kReadsNormal)
  simd::f8 position[3];  // world-space position (kReadsPosition)
  simd::f8 attr[Model::kAttributes > 0 ? Model::kAttributes : 1];  // vertex attributes (kAttributes)
  simd::f8 attr_dx[Model::kAttributes > 0 ? Model::kAttributes : 1];  // their d/dx (kReadUvDerivs)
  simd::f8 attr_dy[Model::kAttributes > 0 ? Model::kAttributes : 1];  // and d/dy
  simd::i8 mine;  // the lanes that are shaded
};

// "unlit": the base colour.
struct UnlitModel {
  static constexpr Shading kId = Shading::Unlit;
  static constexpr const char* kName = "unlit";  // render(shading=...)
  static constexpr bool kReadsNormal = false, kReadsColor = true, kUniformLit = false;
  static constexpr bool kReadsPosition = false, kFaceNormal = false;
  static constexpr int kAttributes = 0;
  static constexpr bool kAttributesIfTextured = false;
  struct Triangle {};
  struct Constants {
    Constants() = default;
    SR_INLINE Constants(const ShadeInputs&, const ShadeTriangle<UnlitModel>&) {}
  };
  static void classify(const ShadeInputs&, bool uniform_color, ShadeTriangle<UnlitModel>& s) {
    if (uniform_color) {
      s.color_kind = ShadeTriangleBase::kConstantColor;
      s.rgb = s.color[0];
    } else {
      s.color_kind = ShadeTriangleBase::kVaryingColor;
    }
  }
  SR_INLINE static void shade(const Constants&, const Fragment<UnlitModel>&, simd::f8&,
                              simd::f8&, simd::f8&) {}
};

// "lambert": base colour * (ambient + (1 - ambient) * max(0, n . l)), l the headlight, two-sided.
struct LambertModel {
  static constexpr Shading kId = Shading::Lambert;
  static constexpr const char* kName = "lambert";  // render(shading=...)
  static constexpr bool kReadsNormal = true, kReadsColor = true, kUniformLit = true;
  static constexpr bool kReadsPosition = false, kFaceNormal = false;
  static constexpr int kAttributes = 0;
  static constexpr bool kAttributesIfTextured = false;
  struct Triangle {
    float light_dot[3];  // kUniformLit: dot(normal[k], to_light_world)
  };
  struct Constants {
    simd::f8 light[3];  // to_light_world, or for kUniformLit the vertices' dot(normal[k], l)
    simd::f8 ambient, diffuse;
    Constants() = default;
    SR_INLINE Constants(const ShadeInputs& in, const ShadeTriangle<LambertModel>& s) {
      for (int k = 0; k < 3; ++k)
        light[k] = s.color_kind == ShadeTriangleBase::kUniformLit ? simd::splat(s.model.light_dot[k])
                                                                  : simd::splat(in.to_light_world[k]);
      ambient = simd::splat(in.ambient);
      diffuse = simd::splat(1.0f - in.ambient);
    }
  };
  static void classify(const ShadeInputs& in, bool uniform_color, ShadeTriangle<LambertModel>& s) {
    if (uniform_color && s.one_normal) {
      s.color_kind = ShadeTriangleBase::kConstantColor;
      s.rgb = s.color[0] * (in.ambient + (1.0f - in.ambient) *
                            std::max(glm::dot(s.unit_normal, in.to_light_world), 0.0f));
    } else if (uniform_color) {
      s.color_kind = ShadeTriangleBase::kUniformLit;
      for (int k = 0; k < 3; ++k) s.model.light_dot[k] = glm::dot(s.normal[k], in.to_light_world);

    } else {
      s.color_kind = ShadeTriangleBase::kVaryingColor;
    }
  }
  SR_INLINE static void shade(const Constants& c, const Fragment<LambertModel>& f, simd::f8& r,
                              simd::f8& g, simd::f8& b) {
    const simd::f8 d = f.normal[0] * c.light[0] + f.normal[1] * c.light[1] + f.normal[2] * c.light[2];
    const simd::f8 lit = c.ambient + c.diffuse * (simd::f8{} < d ? d : simd::f8{});
    r *= lit; g *= lit; b *= lit;
  }
  // The Lambert term dot(n, L) / |n| of the unnormalised interpolated normal, without normalising
  // the weights (both are scale-invariant) or interpolating colours.
  SR_INLINE static simd::f8 shade_uniform(const Constants& c, const ShadeTriangle<LambertModel>& s,
                                          simd::f8 b0, simd::f8 b1, simd::f8 b2) {
    using simd::f8;
    const f8 nx = b0 * s.normal[0].x + b1 * s.normal[1].x + b2 * s.normal[2].x;
    const f8 ny = b0 * s.normal[0].y + b1 * s.normal[1].y + b2 * s.normal[2].y;
    const f8 nz = b0 * s.normal[0].z + b1 * s.normal[1].z + b2 * s.normal[2].z;
    const f8 len2 = nx * nx + ny * ny + nz * nz;
    const f8 dot = b0 * c.light[0] + b1 * c.light[1] + b2 * c.light[2];
    const f8 d = dot / simd::sqrt(len2);  // NaN for a zero normal: no diffuse term
    return c.ambient + c.diffuse * (f8{} < d ? d : f8{});
  }
};

// "normal": the world-space unit normal of the visible side as a colour, (n + 1) / 2 (zero
// normals give mid-grey). Base colours are not read.
struct NormalModel {
  static constexpr Shading kId = Shading::Normal;
  static constexpr const char* kName = "normal";  // render(shading=...)
  static constexpr bool kReadsNormal = true, kReadsColor = false, kUniformLit = false;
  static constexpr bool kReadsPosition = false, kFaceNormal = false;
  static constexpr int kAttributes = 0;
  static constexpr bool kAttributesIfTextured = false;
  struct Triangle {};
  struct Constants {
    Constants() = default;
    SR_INLINE Constants(const ShadeInputs&, const ShadeTriangle<NormalModel>&) {}
  };
  static void classify(const ShadeInputs&, bool, ShadeTriangle<NormalModel>& s) {
    if (s.one_normal) {
      s.color_kind = ShadeTriangleBase::kConstantColor;
      s.rgb = s.unit_normal * 0.5f + 0.5f;
    } else {
      s.color_kind = ShadeTriangleBase::kVaryingColor;
    }
  }
  SR_INLINE static void shade(const Constants&, const Fragment<NormalModel>& f, simd::f8& r,
                              simd::f8& g, simd::f8& b) {
    r = f.normal[0] * 0.5f + 0.5f;
    g = f.normal[1] * 0.5f + 0.5f;
    b = f.normal[2] * 0.5f + 0.5f;
  }
};

// "uv": the mesh's texture coordinates as a colour, (u, v, 0) clamped to [0, 1] (a mesh without
// uvs is black). Reads one two-float vertex attribute, interpolated perspective-correctly.
struct UvModel {
  static constexpr Shading kId = Shading::Uv;
  static constexpr const char* kName = "uv";  // render(shading=...)
  static constexpr bool kReadsNormal = false, kReadsColor = false, kUniformLit = false;
  static constexpr bool kReadsPosition = false, kFaceNormal = false;
  static constexpr int kAttributes = 2;
  static constexpr bool kAttributesIfTextured = false;
  struct Triangle {};
  struct Constants {
    Constants() = default;
    SR_INLINE Constants(const ShadeInputs&, const ShadeTriangle<UvModel>&) {}
  };
  static void classify(const ShadeInputs&, bool, ShadeTriangle<UvModel>& s) {
    const bool one = s.attr[0][0] == s.attr[1][0] && s.attr[0][0] == s.attr[2][0] &&
                     s.attr[0][1] == s.attr[1][1] && s.attr[0][1] == s.attr[2][1];
    if (one) {
      s.color_kind = ShadeTriangleBase::kConstantColor;
      s.rgb = glm::clamp(vec3(s.attr[0][0], s.attr[0][1], 0.0f), 0.0f, 1.0f);
    } else {
      s.color_kind = ShadeTriangleBase::kVaryingColor;
    }
  }
  SR_INLINE static void shade(const Constants&, const Fragment<UvModel>& f, simd::f8& r,
                              simd::f8& g, simd::f8& b) {
    r = simd::clamp01(f.attr[0]);
    g = simd::clamp01(f.attr[1]);
    b = simd::f8{};
  }
};


// "lit" (the names lambert, phong, blinn_phong, pbr with lights, and "auto" with materials): each
// draw's material and reflectance model (Brdf, a per-triangle branch), summed over the render's
// lights, at the render's frequency. lighting.hpp holds the formulas.
struct LitModel {
  static constexpr Shading kId = Shading::Lit;
  static constexpr const char* kName = "lit";  // internal: render.py maps the public names to it
  static constexpr bool kReadsNormal = true, kReadsColor = true, kUniformLit = false;
  static constexpr bool kReadsPosition = true, kFaceNormal = true;
  static constexpr int kAttributes = 2;  // uvs, for a textured material's draws only
  static constexpr bool kAttributesIfTextured = true;
  static constexpr bool kDefersLight = true;
  struct Triangle {
    Brdf brdf;
    bool passthrough;  // the interpolated colour is the radiance (unlit, or Gouraud)
    bool normal_map;   // a normal or bump texture perturbs the pixel's normal (pixel frequency)
    float side;        // -1: a single-sided back face, lit with the normal facing away
    vec3 tangent;      // normal_map: the world-space direction of +u on the triangle (or zero)
    float handedness;  // normal_map: +1, or -1 where the uvs are mirrored (bitangent = -n x t)
  };
  struct Constants {
    const LitInputs* in;
    const Material* material;
    Brdf brdf;
    bool passthrough, positions, textured, normal_map;
    TextureFilter base_filter, emissive_filter, normal_filter, mr_filter, occlusion_filter,
        bump_filter;
    simd::f8 side;
    vec3 tangent;
    float handedness;
    // Nonzero if the tile's light pass lights this triangle's pixels (ShadeScratch::lit_code):
    // a per-pixel lit triangle whose material needs no per-pixel textures after lighting.
    int32_t code;
    // The light pass also normalises its interpolated normals (untextured: nothing before
    // lighting reads them).
    bool raw_normal;
    Constants() = default;
    SR_INLINE Constants(const ShadeInputs& inputs, const ShadeTriangle<LitModel>& s)
        : in(&inputs.lit), material(s.material), brdf(s.model.brdf),
          passthrough(s.model.passthrough),
          positions((s.reads & ShadeTriangleBase::kReadPosition) != 0),
          textured((s.reads & ShadeTriangleBase::kReadUv) != 0), normal_map(s.model.normal_map),
          side(simd::splat(s.model.side)), tangent(s.model.tangent),
          handedness(s.model.handedness) {
      const bool lit = s.color_kind == ShadeTriangleBase::kVaryingColor && !passthrough &&
                       brdf != Brdf::Normal && brdf != Brdf::Unlit;
      const bool after = textured && (s.material->material_maps() || s.material->emissive_texture);
      raw_normal = lit && !textured;
      code = lit && !after ? int32_t(4 * (s.draw + 1) + (raw_normal ? 2 : 0) + (positions ? 1 : 0)) : 0;
      if (textured) {
        const Material& m = *s.material;
        const auto pick = [&](const Texture* t) {
          return inputs.texture_filter != kNoFilterOverride ? TextureFilter(inputs.texture_filter)
                 : t ? t->filter : TextureFilter::Nearest;
        };
        base_filter = pick(m.base_color_texture);
        emissive_filter = pick(m.emissive_texture);
        normal_filter = pick(m.normal_texture);
        mr_filter = pick(m.metallic_roughness_texture);
        occlusion_filter = pick(m.occlusion_texture);
        bump_filter = pick(m.bump_texture);
      }
    }
  };
  // Does the radiance depend on the position (point lights, or the view vector)?
  static bool reads_position(const ShadeInputs& in, const Material& m, Brdf brdf) {
    if (brdf == Brdf::Pbr) return true;
    if ((brdf == Brdf::Phong || brdf == Brdf::BlinnPhong) &&
        (m.ks.x > 0.0f || m.ks.y > 0.0f || m.ks.z > 0.0f))
      return true;
    for (int k = 0; k < in.lit.num_lights; ++k)
      if (in.lit.lights[k].kind != LightKind::Directional) return true;
    return false;
  }
  // Radiance at up to eight points given per lane (per triangle, for the vertex and face
  // frequencies). Out of line, so compiled once per file for the generic target: the same code,
  // and bits, for either instruction set, and not one more inlined light loop per kernel.
  __attribute__((noinline)) static void radiance_at(const ShadeInputs& in, const Material& m, Brdf brdf, const vec3* n,
                          const vec3* p, const vec3* base, int count, vec3* out) {
    simd::f8 nl[3] = {}, pl[3] = {}, bl[3] = {}, o[3];
    for (int i = 0; i < count; ++i)
      for (int c = 0; c < 3; ++c) {
        nl[c][i] = n[i][c];
        pl[c][i] = p[i][c];
        bl[c][i] = base[i][c];
      }
    lit_radiance<true>(in.lit, m, brdf, nl, pl, bl, o);
    for (int i = 0; i < count; ++i) out[i] = vec3(o[0][i], o[1][i], o[2][i]);
  }
  static vec3 unit_or_zero(vec3 v) {
    const float len2 = glm::dot(v, v);
    return len2 > 0.0f ? v * (1.0f / std::sqrt(len2)) : vec3(0.0f);
  }
  static void classify(const ShadeInputs& in, bool uniform_color, ShadeTriangle<LitModel>& s) {
    const Material& m = *s.material;
    const Brdf brdf = m.brdf;
    s.model.brdf = brdf;
    s.model.passthrough = false;
    s.model.side = s.back_facing && !m.double_sided ? -1.0f : 1.0f;
    s.model.normal_map = false;
    s.reads = 0;
    if (m.textured()) {
      classify_textured(in, uniform_color, s);
      return;
    }
    if (brdf == Brdf::Unlit) {
      if (uniform_color) {
        s.color_kind = ShadeTriangleBase::kConstantColor;
        s.rgb = s.color[0];
      } else {
        s.color_kind = ShadeTriangleBase::kVaryingColor;
        s.model.passthrough = true;
      }
      return;
    }
    if (brdf == Brdf::Normal) {  // (n + 1) / 2 at the render's frequency
      if (in.frequency == Frequency::Face || s.one_normal) {
        s.color_kind = ShadeTriangleBase::kConstantColor;
        s.rgb = (in.frequency == Frequency::Face ? s.face_normal : s.unit_normal) * 0.5f + 0.5f;
      } else if (in.frequency == Frequency::Vertex) {
        s.color_kind = ShadeTriangleBase::kVaryingColor;
        for (int k = 0; k < 3; ++k) s.color[k] = unit_or_zero(s.normal[k]) * 0.5f + 0.5f;
        s.model.passthrough = true;
      } else {
        s.color_kind = ShadeTriangleBase::kVaryingColor;
        s.reads = ShadeTriangleBase::kReadNormal;
      }
      return;
    }
    const bool position = reads_position(in, m, brdf);
    const vec3 side(s.model.side);
    if (in.frequency == Frequency::Face ||
        (uniform_color && s.one_normal && !position)) {  // one colour for the whole face
      const vec3 n = in.frequency == Frequency::Face ? s.face_normal : s.unit_normal;
      const vec3 p = (s.position[0] + s.position[1] + s.position[2]) * (1.0f / 3.0f);
      const vec3 base = uniform_color ? s.color[0] : (s.color[0] + s.color[1] + s.color[2]) * (1.0f / 3.0f);
      const vec3 ns = n * side;
      radiance_at(in, m, brdf, &ns, &p, &base, 1, &s.rgb);
      s.color_kind = ShadeTriangleBase::kConstantColor;
      return;
    }
    s.color_kind = ShadeTriangleBase::kVaryingColor;
    if (in.frequency == Frequency::Vertex) {  // Gouraud: light the vertices, interpolate colour
      vec3 n[3], base[3];
      for (int k = 0; k < 3; ++k) {
        n[k] = unit_or_zero(s.normal[k]) * side;
        base[k] = uniform_color ? s.color[0] : s.color[k];
      }
      radiance_at(in, m, brdf, n, s.position, base, 3, s.color);
      s.model.passthrough = true;
      if (s.color[0] == s.color[1] && s.color[0] == s.color[2]) {
        s.color_kind = ShadeTriangleBase::kConstantColor;
        s.rgb = s.color[0];
      }
      return;
    }
    s.reads = ShadeTriangleBase::kReadNormal | (position ? ShadeTriangleBase::kReadPosition : 0);
  }
  // A textured material's triangle: as classify below, but its colour always varies per pixel
  // (the textures are sampled there). The vertex and face frequencies light the vertices or the
  // face with the untextured base colour and modulate the result per pixel by the base colour
  // texture (OpenGL's fixed-function GL_MODULATE), plus the emissive texture; a normal texture
  // is read at the pixel frequency only.
  static void classify_textured(const ShadeInputs& in, bool uniform_color, ShadeTriangle<LitModel>& s) {
    const Material& m = *s.material;
    const Brdf brdf = m.brdf;
    s.color_kind = ShadeTriangleBase::kVaryingColor;
    s.reads = ShadeTriangleBase::kReadUv | ShadeTriangleBase::kReadUvDerivs;
    if (brdf == Brdf::Unlit) {
      s.model.passthrough = true;
      return;
    }
    const vec3 side(s.model.side);
    if (brdf != Brdf::Normal && in.frequency != Frequency::Pixel) {
      s.model.passthrough = true;
      if (in.frequency == Frequency::Face) {
        const vec3 p = (s.position[0] + s.position[1] + s.position[2]) * (1.0f / 3.0f);
        const vec3 base = uniform_color ? s.color[0] : (s.color[0] + s.color[1] + s.color[2]) * (1.0f / 3.0f);
        const vec3 ns = s.face_normal * side;
        vec3 rgb;
        radiance_at(in, m, brdf, &ns, &p, &base, 1, &rgb);
        s.color[0] = s.color[1] = s.color[2] = rgb;
      } else {
        vec3 n[3], base[3];
        for (int k = 0; k < 3; ++k) {
          n[k] = unit_or_zero(s.normal[k]) * side;
          base[k] = uniform_color ? s.color[0] : s.color[k];
        }
        radiance_at(in, m, brdf, n, s.position, base, 3, s.color);
      }
      return;
    }
    if (brdf == Brdf::Normal && in.frequency != Frequency::Pixel) {
      s.model.passthrough = true;
      for (int k = 0; k < 3; ++k)
        s.color[k] = in.frequency == Frequency::Face ? s.face_normal * 0.5f + 0.5f
                                                     : unit_or_zero(s.normal[k]) * 0.5f + 0.5f;
      return;
    }
    s.reads |= ShadeTriangleBase::kReadNormal;
    if (brdf != Brdf::Normal && (reads_position(in, m, brdf) || m.material_maps()))
      s.reads |= ShadeTriangleBase::kReadPosition;
    if (m.normal_texture || m.bump_texture) {
      // The triangle's tangent frame from its positions and uvs (per face, in world space):
      // dp = T du + B dv over its two edges. Mirrored uvs flip the bitangent (handedness).
      s.model.normal_map = true;
      const vec3 e1 = s.position[1] - s.position[0], e2 = s.position[2] - s.position[0];
      const float du1 = s.attr[1][0] - s.attr[0][0], dv1 = s.attr[1][1] - s.attr[0][1];
      const float du2 = s.attr[2][0] - s.attr[0][0], dv2 = s.attr[2][1] - s.attr[0][1];
      const float det = du1 * dv2 - du2 * dv1;
      const vec3 t = (e1 * dv2 - e2 * dv1), bt = (e2 * du1 - e1 * du2);
      const vec3 n = s.normal[0] + s.normal[1] + s.normal[2];  // the visible side
      const float sign = det < 0.0f ? -1.0f : 1.0f;   // t, bt above are det * (T, B)
      s.model.tangent = det != 0.0f && std::isfinite(det) ? unit_or_zero(t * sign) : vec3(0.0f);
      s.model.handedness = glm::dot(glm::cross(n, t * sign), bt * sign) < 0.0f ? -1.0f : 1.0f;
    }
  }
  // Samples `tex` at the fragment's uvs (plus du, dv) into out[0..3] (lanes of f.mine).
  SR_INLINE static void sample(const Texture& tex, TextureFilter filter,
                               const Fragment<LitModel>& f, simd::f8 (&out)[4], float du = 0.0f,
                               float dv = 0.0f) {
    alignas(32) float u[8], v[8], ux[8], vx[8], uy[8], vy[8], o[4][8] = {};
    simd::store(u, f.attr[0] + du); simd::store(v, f.attr[1] + dv);
    simd::store(ux, f.attr_dx[0]); simd::store(vx, f.attr_dx[1]);
    simd::store(uy, f.attr_dy[0]); simd::store(vy, f.attr_dy[1]);
    uint32_t mask = 0;
    for (int i = 0; i < 8; ++i) mask |= uint32_t(f.mine[i] != 0) << i;
    sample_texture8(tex, filter, u, v, ux, vx, uy, vy, mask, o);
    for (int c = 0; c < 4; ++c) out[c] = simd::load<simd::f8>(o[c]);
  }
  // The normal texture's tangent-space normal (2 rgb - 1, x and y scaled by normal_scale, y
  // negated for a DirectX-style map) in the frame (t, b, n): t the triangle's tangent made
  // orthogonal to the pixel's normal n, b = handedness n x t. Where the frame is degenerate (no
  // tangent, a zero normal) n is kept.
  // A bump texture instead (the course notes): heights h at the pixel's uv and one texel
  // further along u and along v, dU = bump_scale (h(u + 1/w) - h), dV = bump_scale (h(v + 1/h) - h),
  // and the tangent-space normal (-dU, -dV, 1) in the same frame.
  SR_INLINE static void normal_map(const Constants& c, const Fragment<LitModel>& f, simd::f8 (&n)[3]) {
    using simd::f8;
    f8 tx, ty, tz;
    if (c.material->normal_texture) {
      f8 tex[4];
      sample(*c.material->normal_texture, c.normal_filter, f, tex);
      const float scale = c.material->normal_scale;
      tx = (tex[0] * 2.0f - 1.0f) * scale;
      ty = (tex[1] * 2.0f - 1.0f) * (c.material->normal_y_down ? -scale : scale);
      tz = tex[2] * 2.0f - 1.0f;
    } else {
      const Texture& bump = *c.material->bump_texture;
      f8 h0[4], hu[4], hv[4];
      sample(bump, c.bump_filter, f, h0);
      sample(bump, c.bump_filter, f, hu, 1.0f / float(bump.width()), 0.0f);
      sample(bump, c.bump_filter, f, hv, 0.0f, 1.0f / float(bump.height()));
      const float k = c.material->bump_scale;
      tx = (h0[0] - hu[0]) * k;
      ty = (h0[0] - hv[0]) * k;
      tz = simd::splat(1.0f);
    }
    const f8 nt = n[0] * c.tangent.x + n[1] * c.tangent.y + n[2] * c.tangent.z;
    f8 t[3];
    for (int k = 0; k < 3; ++k) t[k] = c.tangent[k] - n[k] * nt;
    const f8 tlen2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    const f8 tr = 1.0f / simd::sqrt(tlen2);
    for (int k = 0; k < 3; ++k) t[k] *= tr;
    const f8 b[3] = {(n[1] * t[2] - n[2] * t[1]) * c.handedness, (n[2] * t[0] - n[0] * t[2]) * c.handedness,
                     (n[0] * t[1] - n[1] * t[0]) * c.handedness};
    f8 m[3];
    for (int k = 0; k < 3; ++k) m[k] = t[k] * tx + b[k] * ty + n[k] * tz;
    const f8 len2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
    const f8 r = 1.0f / simd::sqrt(len2);
    const simd::i8 ok = (tlen2 > 0.0f) & (len2 > 0.0f) & (r == r);
    for (int k = 0; k < 3; ++k) n[k] = ok ? m[k] * r : n[k];
  }
  // What lighting reads of a pixel (code != 0): the normal, perturbed by a normal texture and
  // turned toward the lit side, and the base colour times the base colour texture.
  SR_INLINE static void surface(const Constants& c, const Fragment<LitModel>& f, simd::f8 (&n)[3],
                                simd::f8& r, simd::f8& g, simd::f8& b) {
    for (int k = 0; k < 3; ++k) n[k] = f.normal[k];
    if (c.textured) {
      if (c.normal_map) normal_map(c, f, n);
      if (c.material->base_color_texture) {
        simd::f8 tex[4];
        sample(*c.material->base_color_texture, c.base_filter, f, tex);
        r *= tex[0]; g *= tex[1]; b *= tex[2];
      }
    }
    for (int k = 0; k < 3; ++k) n[k] *= c.side;
  }
  SR_INLINE static void shade(const Constants& c, const Fragment<LitModel>& f, simd::f8& r,
                              simd::f8& g, simd::f8& b) {
    using simd::f8;
    f8 n[3] = {f.normal[0], f.normal[1], f.normal[2]};
    if (c.textured) {
      if (c.normal_map) normal_map(c, f, n);
      if (c.material->base_color_texture && c.brdf != Brdf::Normal) {
        f8 tex[4];
        sample(*c.material->base_color_texture, c.base_filter, f, tex);
        r *= tex[0]; g *= tex[1]; b *= tex[2];
      }
    }
    if (c.passthrough) {
      if (c.textured && c.brdf != Brdf::Unlit && c.brdf != Brdf::Normal) add_emissive(c, f, r, g, b);
      return;
    }
    if (c.brdf == Brdf::Normal) {
      r = n[0] * 0.5f + 0.5f;
      g = n[1] * 0.5f + 0.5f;
      b = n[2] * 0.5f + 0.5f;
      return;
    }
    for (int k = 0; k < 3; ++k) n[k] *= c.side;
    const f8 base[3] = {r, g, b};
    f8 out[3];
    if (c.textured && c.material->material_maps())
      material_maps(c, f, n, base, out);
    else if (c.positions)
      lit_radiance<true>(*c.in, *c.material, c.brdf, n, f.position, base, out);
    else
      lit_radiance<false>(*c.in, *c.material, c.brdf, n, f.position, base, out);
    r = out[0];
    g = out[1];
    b = out[2];
    if (c.textured) add_emissive(c, f, r, g, b);
  }
  // Radiance with per-pixel metallic, roughness (glTF: the factors times the texture's blue and
  // green) and ambient occlusion (ambient times 1 + strength (red - 1)), out of line.
  __attribute__((noinline)) static void material_maps(const Constants& c, const Fragment<LitModel>& f,
                                                      const simd::f8 (&n)[3], const simd::f8 (&base)[3],
                                                      simd::f8 (&out)[3]) {
    const Material& m = *c.material;
    MaterialLanes lanes{simd::splat(m.metallic), simd::splat(m.roughness), simd::splat(1.0f)};
    if (m.metallic_roughness_texture) {
      simd::f8 tex[4];
      sample(*m.metallic_roughness_texture, c.mr_filter, f, tex);
      lanes.roughness = tex[1] * m.roughness;
      lanes.metallic = tex[2] * m.metallic;
    }
    if (m.occlusion_texture) {
      simd::f8 tex[4];
      sample(*m.occlusion_texture, c.occlusion_filter, f, tex);
      lanes.occlusion = 1.0f + (tex[0] - 1.0f) * m.occlusion_strength;
    }
    lit_radiance_lanes(*c.in, m, c.brdf, n, f.position, base, lanes, out);
  }
  SR_INLINE static void add_emissive(const Constants& c, const Fragment<LitModel>& f, simd::f8& r,
                                     simd::f8& g, simd::f8& b) {
    if (!c.material->emissive_texture) return;
    simd::f8 tex[4];
    sample(*c.material->emissive_texture, c.emissive_filter, f, tex);
    const vec3 e = c.material->emissive_factor;
    r += tex[0] * e.x; g += tex[1] * e.y; b += tex[2] * e.z;
  }
};

// Model::kDefersLight, false where the model does not name it.
template <typename Model, typename = void>
struct DefersLight : std::false_type {};
template <typename Model>
struct DefersLight<Model, std::void_t<decltype(Model::kDefersLight)>>
    : std::bool_constant<Model::kDefersLight> {};

// Every model the kernels are compiled for, in Shading's order.
template <typename... M>
struct ModelList {};
using ShadingModels = ModelList<UnlitModel, LambertModel, NormalModel, UvModel, LitModel>;
template <typename... M>
constexpr int count_models(ModelList<M...>) { return int(sizeof...(M)); }
constexpr int kNumShadingModels = count_models(ShadingModels{});
// Every model's (Shading, name), in list order.
struct ModelName {
  Shading id;
  const char* name;
};
template <typename... M>
constexpr std::array<ModelName, sizeof...(M)> model_names(ModelList<M...>) {
  return {ModelName{M::kId, M::kName}...};
}
inline constexpr auto kShadingModelNames = model_names(ShadingModels{});

// True if `shading`'s colour reads normals (then a colour render prepares world normals).
template <typename... M>
constexpr bool reads_normal(Shading shading, ModelList<M...>) {
  return ((M::kId == shading && M::kReadsNormal) || ...);
}
constexpr bool model_reads_normal(Shading shading) { return reads_normal(shading, ShadingModels{}); }

}  // namespace sr
