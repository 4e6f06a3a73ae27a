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
// Give it a Shading value (pipeline.hpp) and list it in ShadingModels below: the dispatch
// compiles kernels for every listed model, and bindings.cpp exports the names to Python
// (softrast's render(shading=) and the CLI) from the list (ARCHITECTURE.md, "Add a shading model").
#pragma once

#include "lighting.hpp"
#include "pipeline.hpp"
#include "simd.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace sr {

// Per-render values every model may read.
struct ShadeInputs {
  vec3 to_light_world;  // unit vector toward the headlight (= toward the camera)
  float ambient;        // Lambert: ambient + (1 - ambient) * max(0, n . l)
  LitInputs lit;        // the lit model: lights, ambient light, eye
  Frequency frequency = Frequency::Pixel;
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
  enum Reads : uint8_t { kReadNormal = 1, kReadPosition = 2 };  // bits of `reads`
  float persp[3];   // 1 / (w_k * area2) / max_k(1 / w_k): E_k * persp[k] ~ perspective-correct
                    // weight, scaled so that the largest is about 1 (no float underflow)
  vec3 normal[3];   // world-space normal at each vertex (the face normal if flat), facing the
                    // camera's side for back faces; zero unless normals are read
  vec3 color[3];    // base colour at each vertex (only color[0] set where all are equal)
  ColorKind color_kind;
  bool one_normal;     // the three normals are equal
  bool back_facing;    // the camera sees the triangle's back (normals are flipped to face it)
  uint8_t reads;       // kVaryingColor: what the model's shade reads beyond the base colour
                       // (Reads bits; the model's flags unless classify() clears some)
  vec3 rgb;            // kConstantColor: the linear radiance of every pixel
  vec3 unit_normal;    // one_normal: the unit normal of every pixel (zero if the normal is zero)
  const Material* material;  // the draw's
};
template <typename Model>
struct ShadeTriangle : ShadeTriangleBase {
  typename Model::Triangle model;
  vec3 position[Model::kReadsPosition ? 3 : 1];  // world space at each vertex (kReadsPosition)
  vec3 face_normal;  // kFaceNormal and frequency "face": the unit face normal, visible side
  float attr[3][Model::kAttributes > 0 ? Model::kAttributes : 1];  // at each vertex (kAttributes)
};

// What a model reads at eight pixels, interpolated with perspective-correct weights. Only what
// its flags ask for is computed; the rest is left unset.
template <typename Model>
struct Fragment {
  simd::f8 normal[3];    // world-space unit normal of the visible side (kReadsNormal)
  simd::f8 position[3];  // world-space position (kReadsPosition)
  simd::f8 attr[Model::kAttributes > 0 ? Model::kAttributes : 1];  // vertex attributes (kAttributes)
};

// "unlit": the base colour.
struct UnlitModel {
  static constexpr Shading kId = Shading::Unlit;
  static constexpr const char* kName = "unlit";  // render(shading=...)
  static constexpr bool kReadsNormal = false, kReadsColor = true, kUniformLit = false;
  static constexpr bool kReadsPosition = false, kFaceNormal = false;
  static constexpr int kAttributes = 0;
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
  static constexpr int kAttributes = 0;
  struct Triangle {
    Brdf brdf;
    bool passthrough;  // the interpolated colour is the radiance (unlit, or Gouraud)
    float side;        // -1: a single-sided back face, lit with the normal facing away
  };
  struct Constants {
    const LitInputs* in;
    const Material* material;
    Brdf brdf;
    bool passthrough, positions;
    simd::f8 side;
    Constants() = default;
    SR_INLINE Constants(const ShadeInputs& inputs, const ShadeTriangle<LitModel>& s)
        : in(&inputs.lit), material(s.material), brdf(s.model.brdf),
          passthrough(s.model.passthrough),
          positions((s.reads & ShadeTriangleBase::kReadPosition) != 0),
          side(simd::splat(s.model.side)) {}
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
    s.reads = 0;
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
  SR_INLINE static void shade(const Constants& c, const Fragment<LitModel>& f, simd::f8& r,
                              simd::f8& g, simd::f8& b) {
    using simd::f8;
    if (c.passthrough) return;
    if (c.brdf == Brdf::Normal) {
      r = f.normal[0] * 0.5f + 0.5f;
      g = f.normal[1] * 0.5f + 0.5f;
      b = f.normal[2] * 0.5f + 0.5f;
      return;
    }
    const f8 n[3] = {f.normal[0] * c.side, f.normal[1] * c.side, f.normal[2] * c.side};
    const f8 base[3] = {r, g, b};
    f8 out[3];
    if (c.positions)
      lit_radiance<true>(*c.in, *c.material, c.brdf, n, f.position, base, out);
    else
      lit_radiance<false>(*c.in, *c.material, c.brdf, n, f.position, base, out);
    r = out[0];
    g = out[1];
    b = out[2];
  }
};

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
