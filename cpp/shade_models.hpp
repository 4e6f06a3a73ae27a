// Shading of a visible triangle: what is prepared once for all its pixels (ShadeTriangle,
// classify) and how its pixels are shaded eight at a time (ShadeConstants, shade_pixel).
//
// There is one description for every draw. A draw's reflectance model (Brdf: its material's, or
// the one the render's shading= names, chosen once per draw by the plan) is a per-triangle
// branch, never a kernel variant: the shading kernels (shade_kernels.hpp) are compiled once per
// instruction set, and a model or debug view adds code here, not kernels (ARCHITECTURE.md, "Add a
// shading model"). What a triangle does not read is never fetched or interpolated: classify sets
// `reads`, and the draw's needs (ShadeDraw) decide what prepare() fetches.
//
// The per-pixel work of each kind of triangle:
//   constant colour  every pixel one colour, computed by classify (s.rgb): unlit and uniform
//                    triangles, the face frequency, Gouraud triangles of one colour;
//   uniformly lit    the headlight's Lambert on a triangle of one base colour whose normals vary
//                    (shade_uniform: no normalised weights, no colour interpolation);
//   varying          normalised perspective weights, what `reads` asks for interpolated, then
//                    the draw's formula: the interpolated colour (unlit, Gouraud), the
//                    headlight's Lambert, the normal or uv as a colour, inline; lights and
//                    textures out of line (lit_kernels.hpp): a lit pixel's lighting is left to
//                    the tile's light pass, a textured pixel's textures are sampled by a
//                    function compiled once per instruction set.
#pragma once

#include "lighting.hpp"
#include "pipeline.hpp"
#include "simd.hpp"
#include "texture.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace sr {

struct LitKernels;  // lit_kernels.hpp

// Per-render values every triangle may read.
struct ShadeInputs {
  vec3 to_light_world;  // unit vector toward the headlight (= toward the camera)
  float ambient;        // the headlight's Lambert: ambient + (1 - ambient) * max(0, n . l)
  LitInputs lit;        // lit draws: lights, ambient light, eye
  Frequency frequency = Frequency::Pixel;
  uint8_t texture_filter = kNoFilterOverride;  // a TextureFilter for every texture, or each its own
  bool defers_light = false;  // some draw's pixels are lit by the tile's light pass
  // The normal output has normal and bump maps applied (render(normal_kind="shading"), the
  // pixel frequency): the draws with such maps take the lit kernel's textured path.
  bool shading_normals = false;
  vec4 depth_grey{0.0f};      // the depth view: grey = dot(xyz, world position) + w, clamped
};

// std::clamp(v, 0, 1) * 255 + 0.5 truncated.
// (NaN gives 0.)
inline uint32_t to_unorm8(float v) {
  v = v > 0.0f ? v : 0.0f;
  return uint32_t((v < 1.0f ? v : 1.0f) * 255.0f + 0.5f);
}

// std::clamp(v, 0, 1) * 255 + 0.5 truncated, per lane, as to_unorm8 does.
SR_INLINE simd::i8 to_unorm8(simd::f8 v) {
  const simd::f8 zero = simd::splat(0.0f), one = simd::splat(1.0f);
  const simd::f8 c0 = zero < v ? v : zero;  // NaN -> 0
  const simd::f8 c = c0 < one ? c0 : one;
  return __builtin_convertvector(c * 255.0f + 0.5f, simd::i8);
}

// The shading kernels' one axis besides the instruction set and the path (shade_kernels.hpp):
// the lit kernel shades every draw, each triangle by its draw's model; a plain kernel shades one
// model known at compile time (the headlight's Lambert, the base colour, the normal as a colour),
// and a render whose draws all take that model runs it instead: the default render of a mesh
// without a material, shading="unlit" and shading="normal". Each pays for itself (3.0%, 2.2%
// and 11% fewer instructions per frame; without the unlit one, unlit frames took 5% more than
// before this design): benchmarks/RESULTS.md, "What each kernel axis is worth". Everything else
// is a per-draw or per-triangle branch.
enum class KernelKind : uint8_t { Lit, Headlight, Unlit, NormalColor };

// A plain kernel's model, or (the lit kernel) the draw's own.
template <KernelKind K>
constexpr Brdf kernel_brdf(Brdf draws) {
  return K == KernelKind::Headlight ? Brdf::Headlight
         : K == KernelKind::Unlit   ? Brdf::Unlit
         : K == KernelKind::NormalColor ? Brdf::Normal
                                        : draws;
}

// What a draw's triangles read, chosen once per draw by the plan (renderer.cpp, ShadeDraw::needs):
// what prepare() fetches for each visible triangle, and whether it is classified inline.
enum DrawNeeds : uint8_t {
  kNeedsNormal = 1,      // vertex normals (the model reads them, or the normal output)
  kNeedsPosition = 2,    // world positions (lights, the view vector, a tangent frame)
  kNeedsUv = 4,          // the uvs (textures, or the uv model)
  kTexturedUv = 8,       // uvs for sampling: shifted by whole periods, with derivatives
  kNeedsFaceNormal = 16, // the face normal (the face frequency)
  kInline = 32           // classified inline (classify below): the headlight, the uv and depth views,
                         // untextured unlit and (pixel frequency) normal draws
};

// A triangle visible in the tile being shaded, prepared once for all its pixels
// (interpolate.hpp, prepare; then classify). What varies across it picks the work per pixel;
// each output is decided on its own, so an output's bits do not depend on which other outputs
// were requested:
//   colour  kConstantColor  every pixel has one colour, precomputed (s.rgb);
//           kUniformLit     one base colour, normals varying, the headlight: shade_uniform;
//           kVaryingColor   normalised weights, what `reads` asks for interpolated, then
//                           shade_pixel (or the light pass);
//   normal  one_normal: the precomputed unit normal, else the normalised interpolated normal.
struct ShadeTriangle {
  enum ColorKind : uint8_t { kVaryingColor, kUniformLit, kConstantColor };
  // Bits of `reads` (kVaryingColor): what a pixel interpolates. kReadUv interpolates the
  // attributes, kReadUvDerivs also their screen derivatives (d/dx, d/dy per pixel, exact from the
  // triangle's plane equations).
  enum Reads : uint8_t {
    kReadNormal = 1, kReadPosition = 2, kReadUv = 4, kReadUvDerivs = 8, kReadColor = 16
  };
  float persp[3];   // 1 / (w_k * area2) / max_k(1 / w_k): E_k * persp[k] ~ perspective-correct
                    // weight, scaled so that the largest is about 1 (no float underflow)
  // The exact weights (pipeline.hpp, ExactWeights), or null where setup wrote none. `exact`:
  // everything the triangle interpolates reads them (ShadeDraw::exact_shading), not persp.
  const float (*q)[3];
  bool exact;
  vec3 normal[3];   // world-space normal at each vertex (the face normal if flat), facing the
                    // camera's side for back faces; unset unless the draw's normals are read
  vec3 color[3];    // base colour at each vertex (vertex colours, else the draw's colour)
  ColorKind color_kind;
  bool uniform_color;  // the three colours are equal (after classify: Gouraud sets them), read as is
  bool one_normal;     // the three normals are equal
  uint8_t reads;       // Reads bits (kVaryingColor)
  vec3 rgb;            // kConstantColor: the linear radiance of every pixel
  vec3 unit_normal;    // one_normal: the unit normal of every pixel (zero if the normal is zero)
  // The draw (set for the draws classified out of line, classify_lit):
  Brdf brdf;                 // its model
  const Material* material;  // its material
  uint32_t draw;             // its index
  bool back_facing;          // the camera sees the triangle's back (normals are flipped to face it)
  // kUniformLit (the headlight): dot(normal[k], to_light_world).
  float light_dot[3];
  // Lit and textured draws:
  bool passthrough;  // the interpolated colour is the radiance (unlit, or Gouraud)
  bool normal_map;   // a normal or bump texture perturbs the pixel's normal (pixel frequency)
  bool normal_out_map;  // ... and the normal output too (ShadeInputs::shading_normals)
  float side;        // -1: a single-sided back face, lit with the normal facing away
  vec3 tangent;      // normal_map: the world-space direction of +u on the triangle (or zero)
  float handedness;  // normal_map: +1, or -1 where the uvs are mirrored (bitangent = -n x t)
  vec3 position[3];  // world space at each vertex (kNeedsPosition)
  vec3 face_normal;  // kNeedsFaceNormal: the unit face normal, visible side
  float attr[3][2];  // the uvs at each vertex (kNeedsUv)
  // kReadUvDerivs: the x and y derivatives of the unnormalised weights' sum S = sum_k b_k and of
  // sum_k b_k attr_k; an attribute's derivative is then (A_x - attr * S_x) / S at each pixel.
  float sum_dx, sum_dy;
  float attr_dx[2], attr_dy[2];
};

// What a pixel reads at eight pixels, interpolated with perspective-correct weights. Only what
// the triangle's `reads` asks for is computed; the rest is left unset.
struct Fragment {
  simd::f8 normal[3];    // world-space unit normal of the visible side (kReadNormal)
  simd::f8 position[3];  // world-space position (kReadPosition)
  simd::f8 attr[2];      // uvs (kReadUv)
  simd::f8 attr_dx[2];   // their d/dx (kReadUvDerivs)
  simd::f8 attr_dy[2];   // and d/dy
  simd::i8 mine;         // the lanes that are shaded
};

// Per-triangle values of the per-pixel formulas, splatted to eight lanes (built once per visible
// triangle, shade_kernels.hpp).
struct ShadeConstants {
  enum Op : uint8_t { kPassthrough, kHeadlight, kNormalColor, kUvColor, kDepthColor, kOutOfLine };
  simd::f8 persp[3];
  Op op;             // kVaryingColor's formula (the light pass's pixels: see code)
  bool raw_normal;   // the light pass normalises the interpolated normal (untextured lit)
  bool textured;
  // Nonzero if the tile's light pass lights this triangle's pixels (ShadeScratch::lit_code):
  // 4 (draw + 1), + 2 if the normal is still to be normalised, + 1 if lighting reads positions.
  int32_t code;
  // The headlight: the light direction (for kUniformLit the vertices' dot(normal[k], l)),
  // ambient and diffuse weights.
  simd::f8 light[3];
  simd::f8 ambient, diffuse;
  // The depth view (kDepthColor): grey = clamp(dot(grey[0..2], position) + grey[3], 0, 1).
  simd::f8 grey[4];
  // Lit and textured draws (lit_kernels.hpp reads them out of line):
  simd::f8 side;
  const LitInputs* in;
  const Material* material;
  const LitKernels* kernels;
  Brdf brdf;
  bool passthrough, positions, normal_map;
  TextureFilter base_filter, emissive_filter, normal_filter, mr_filter, occlusion_filter,
      bump_filter, specular_filter;
  vec3 tangent;
  float handedness;
};

// Out of line (shade_models.cpp): classify and make_constants for the draws whose triangles do
// more than the inline cases below (lit, textured, and the vertex and face frequencies).
void classify_lit(const ShadeInputs& in, bool uniform_color, ShadeTriangle& s);
void make_lit_constants(const ShadeInputs& in, const LitKernels* kernels, const ShadeTriangle& s,
                        ShadeConstants& c);

// What make_lit_constants last wrote into one ShadeConstants, by the triangle fields it reads: the
// next triangle with the same ones (most of a draw's, in a tile) keeps that output instead of
// making it again (it cost ~1.5 M instructions a frame, 2% of a lit frame of small triangles).
// Valid while nothing else has written those constants; never with a tangent frame (per triangle:
// a normal or bump map, for the colour or for normal_kind="shading").
struct LitConstantsCache {
  const Material* material = nullptr;
  uint32_t draw = 0;
  float side = 0.0f;
  Brdf brdf{};
  uint8_t reads = 0;
  bool passthrough = false, varying = false;
  bool valid = false;
  // make_constants resets these before it calls make_lit_constants:
  int32_t code = 0;
  bool raw_normal = false, textured = false;

  SR_INLINE bool same(const ShadeTriangle& s) const {
    return s.material == material && s.draw == draw && s.side == side && s.brdf == brdf &&
           s.reads == reads && s.passthrough == passthrough &&
           (s.color_kind == ShadeTriangle::kVaryingColor) == varying && !s.normal_map &&
           !s.normal_out_map;
  }
  SR_INLINE void keep(const ShadeTriangle& s, const ShadeConstants& c) {
    material = s.material;
    draw = s.draw;
    side = s.side;
    brdf = s.brdf;
    reads = s.reads;
    passthrough = s.passthrough;
    varying = s.color_kind == ShadeTriangle::kVaryingColor;
    code = c.code;
    raw_normal = c.raw_normal;
    textured = c.textured;
    valid = !s.normal_map && !s.normal_out_map;
  }
};

// What classify_lit decided for the last triangle whose decision depends only on its draw, its
// side and whether its colours and normals are uniform: the pixel frequency, untextured, no
// tangent frame, a colour lit per pixel (the common lit triangle). The next triangle with the same
// ones takes that decision (classify_lit cost ~2.2 M instructions a frame, 3% of a lit frame of
// small triangles). Kept across the triangles one Prepared is made for (shade_kernels.hpp).
struct LitClassCache {
  const Material* material = nullptr;
  uint32_t draw = 0;
  Brdf brdf{};
  bool back_facing = false, uniform_color = false, one_normal = false, valid = false;
  float side = 1.0f;  // classify_lit's outputs (the rest are the same for every such triangle)
  uint8_t reads = 0;
};

// make_lit_constants, or what it wrote last time when `cached` and the triangle reads the same.
SR_INLINE void lit_constants(const ShadeInputs& in, const LitKernels* kernels, const ShadeTriangle& s,
                             bool cached, ShadeConstants& c, LitConstantsCache& cache) {
  if (cached && cache.same(s)) {
    c.code = cache.code;
    c.raw_normal = cache.raw_normal;
    c.textured = cache.textured;
    cache.valid = true;
    return;
  }
  make_lit_constants(in, kernels, s, c);
  cache.keep(s, c);
}

// An unlit triangle's colour: one constant, or the interpolated colour passed through.
SR_INLINE void classify_unlit(bool uniform_color, ShadeTriangle& s) {
  if (uniform_color) {
    s.color_kind = ShadeTriangle::kConstantColor;
    s.rgb = s.color[0];
  } else {
    s.color_kind = ShadeTriangle::kVaryingColor;
    s.passthrough = true;
  }
}

// Picks the triangle's colour kind and what its pixels read, from its draw's model (brdf), needs,
// material and index and the render's frequency. uniform_color: the three base colours are
// equal. The headlight, the uv and depth views, and untextured unlit and normal draws at the pixel
// frequency are classified inline; the kernels without the lit path (kLit false) see no other
// draws, nor the views. Only what later reads is written.
// `cache`: classify_lit's last decision that others may share (LitClassCache).
template <KernelKind K>
SR_INLINE void classify(const ShadeInputs& in, Brdf draw_brdf, uint8_t needs, const Material& m,
                        uint32_t draw, bool back_facing, bool uniform_color, ShadeTriangle& s,
                        LitClassCache& cache) {
  constexpr bool kLit = K == KernelKind::Lit;
  const Brdf brdf = kernel_brdf<K>(draw_brdf);
  if (K == KernelKind::Headlight || K == KernelKind::NormalColor || (needs & kNeedsNormal)) {
    s.one_normal = s.normal[0] == s.normal[1] && s.normal[0] == s.normal[2];
    if (s.one_normal) {
      const vec3 n = s.normal[0];
      const float len2 = glm::dot(n, n);
      s.unit_normal = len2 > 0.0f ? n * (1.0f / std::sqrt(len2)) : vec3(0.0f);
    }
  } else {  // (nothing reads them)
    s.one_normal = true;
    s.unit_normal = vec3(0.0f);
  }
  s.passthrough = false;
  s.normal_out_map = false;
  if (kLit && !(needs & kInline)) {
    s.brdf = brdf;
    s.material = &m;
    s.draw = draw;
    s.back_facing = back_facing;
    if (cache.valid && cache.draw == draw && cache.material == &m && cache.brdf == brdf &&
        cache.back_facing == back_facing && cache.uniform_color == uniform_color &&
        cache.one_normal == s.one_normal) {
      s.side = cache.side;
      s.reads = cache.reads;
      s.color_kind = ShadeTriangle::kVaryingColor;
      s.normal_map = false;
      s.tangent = vec3(0.0f);
      s.handedness = 1.0f;
    } else {
      classify_lit(in, uniform_color, s);
      cache.valid = in.frequency == Frequency::Pixel && !m.textured() &&
                    s.color_kind == ShadeTriangle::kVaryingColor && !s.passthrough &&
                    !s.normal_map && !s.normal_out_map && brdf != Brdf::Normal &&
                    brdf != Brdf::Unlit;
      cache.material = &m;
      cache.draw = draw;
      cache.brdf = brdf;
      cache.back_facing = back_facing;
      cache.uniform_color = uniform_color;
      cache.one_normal = s.one_normal;
      cache.side = s.side;
      cache.reads = s.reads;
    }
    // (after classify, which may put the vertices' radiance in the colours: Gouraud)
    s.uniform_color = s.color[0] == s.color[1] && s.color[0] == s.color[2];
    return;
  }
  s.uniform_color = uniform_color;
  if (brdf == Brdf::Headlight) {  // the headlight's Lambert (a plain scene)
    s.reads = ShadeTriangle::kReadNormal | ShadeTriangle::kReadColor;
    if (uniform_color && s.one_normal) {
      s.color_kind = ShadeTriangle::kConstantColor;
      s.rgb = s.color[0] * (in.ambient + (1.0f - in.ambient) *
                            std::max(glm::dot(s.unit_normal, in.to_light_world), 0.0f));
    } else if (uniform_color) {
      s.color_kind = ShadeTriangle::kUniformLit;
      for (int k = 0; k < 3; ++k) s.light_dot[k] = glm::dot(s.normal[k], in.to_light_world);
    } else {
      s.color_kind = ShadeTriangle::kVaryingColor;
    }
  } else if (kLit && brdf == Brdf::Uv) {  // (u, v, 0) clamped to [0, 1], the mesh's own uvs
    const bool one = s.attr[0][0] == s.attr[1][0] && s.attr[0][0] == s.attr[2][0] &&
                     s.attr[0][1] == s.attr[1][1] && s.attr[0][1] == s.attr[2][1];
    s.reads = ShadeTriangle::kReadUv;
    if (one) {
      s.color_kind = ShadeTriangle::kConstantColor;
      s.rgb = glm::clamp(vec3(s.attr[0][0], s.attr[0][1], 0.0f), 0.0f, 1.0f);
    } else {
      s.color_kind = ShadeTriangle::kVaryingColor;
    }
  } else if (kLit && brdf == Brdf::Depth) {  // (far - depth) / (far - near) as a grey, clamped
    s.reads = ShadeTriangle::kReadPosition;
    float grey[3];
    for (int k = 0; k < 3; ++k) grey[k] = glm::dot(vec3(in.depth_grey), s.position[k]) + in.depth_grey.w;
    if (grey[0] == grey[1] && grey[0] == grey[2]) {
      s.color_kind = ShadeTriangle::kConstantColor;
      s.rgb = vec3(std::clamp(grey[0], 0.0f, 1.0f));
    } else {
      s.color_kind = ShadeTriangle::kVaryingColor;
    }
  } else if (brdf == Brdf::Unlit) {  // the base colour
    s.reads = ShadeTriangle::kReadColor;
    classify_unlit(uniform_color, s);
  } else {  // (n + 1) / 2 per pixel
    s.reads = ShadeTriangle::kReadNormal;
    if (s.one_normal) {
      s.color_kind = ShadeTriangle::kConstantColor;
      s.rgb = s.unit_normal * 0.5f + 0.5f;
    } else {
      s.color_kind = ShadeTriangle::kVaryingColor;
    }
  }
}

// The per-triangle constants of a classified triangle; out of line for lit and textured draws.
// persp: the perspective weights are read (a varying colour or normal, or uniformly lit).
// `cache`: what make_lit_constants last wrote into c (LitConstantsCache).
template <KernelKind K>
SR_INLINE void make_constants(const ShadeInputs& in, const LitKernels* kernels, Brdf draw_brdf,
                              bool persp, const ShadeTriangle& s, ShadeConstants& c,
                              LitConstantsCache& cache) {
  constexpr bool kLit = K == KernelKind::Lit;
  const Brdf brdf = kernel_brdf<K>(draw_brdf);
  if (persp)
    for (int k = 0; k < 3; ++k) c.persp[k] = simd::splat(s.persp[k]);
  bool cached = false;
  if (kLit) {
    c.code = 0;
    c.raw_normal = false;
    c.textured = false;
    cached = cache.valid;
    cache.valid = false;  // (until lit_constants says otherwise: every other path writes c)
  }
  if (s.color_kind == ShadeTriangle::kConstantColor) return;  // (s.rgb: nothing per pixel)
  switch (brdf) {
    case Brdf::Headlight:
      c.op = ShadeConstants::kHeadlight;
      for (int k = 0; k < 3; ++k)
        c.light[k] = s.color_kind == ShadeTriangle::kUniformLit ? simd::splat(s.light_dot[k])
                                                                : simd::splat(in.to_light_world[k]);
      c.ambient = simd::splat(in.ambient);
      c.diffuse = simd::splat(1.0f - in.ambient);
      return;
    case Brdf::Uv:
      c.op = ShadeConstants::kUvColor;
      return;
    case Brdf::Depth:
      c.op = ShadeConstants::kDepthColor;
      for (int k = 0; k < 4; ++k) c.grey[k] = simd::splat(in.depth_grey[k]);
      return;
    default:
      break;
  }
  if (kLit && (s.reads & ShadeTriangle::kReadUv)) {  // textured
    lit_constants(in, kernels, s, cached, c, cache);
  } else if (s.passthrough) {  // unlit, or Gouraud
    c.op = ShadeConstants::kPassthrough;
  } else if (!kLit || brdf == Brdf::Normal) {
    c.op = ShadeConstants::kNormalColor;
  } else {
    lit_constants(in, kernels, s, cached, c, cache);
  }
}

// A varying-colour pixel's inline formulas: base colour r, g, b (kReadColor) and the Fragment in,
// linear radiance out. Lit pixels never come here (the light pass), nor textured ones
// (kOutOfLine: lit_kernels.hpp).
template <KernelKind K>
SR_INLINE void shade_inline(const ShadeConstants& c, const Fragment& f, simd::f8& r, simd::f8& g,
                            simd::f8& b) {
  using simd::f8;
  constexpr bool kLit = K == KernelKind::Lit;
  const ShadeConstants::Op op = K == KernelKind::Headlight     ? ShadeConstants::kHeadlight
                                : K == KernelKind::Unlit       ? ShadeConstants::kPassthrough
                                : K == KernelKind::NormalColor ? ShadeConstants::kNormalColor
                                                               : c.op;
  switch (op) {
    case ShadeConstants::kHeadlight: {  // base colour * (ambient + (1 - ambient) max(0, n . l))
      const f8 d = f.normal[0] * c.light[0] + f.normal[1] * c.light[1] + f.normal[2] * c.light[2];
      const f8 lit = c.ambient + c.diffuse * (f8{} < d ? d : f8{});
      r *= lit; g *= lit; b *= lit;
      return;
    }
    case ShadeConstants::kNormalColor:  // (n + 1) / 2
      r = f.normal[0] * 0.5f + 0.5f;
      g = f.normal[1] * 0.5f + 0.5f;
      b = f.normal[2] * 0.5f + 0.5f;
      return;
    case ShadeConstants::kUvColor:  // (u, v, 0) clamped to [0, 1]
      if (!kLit) return;
      r = simd::clamp01(f.attr[0]);
      g = simd::clamp01(f.attr[1]);
      b = f8{};
      return;
    case ShadeConstants::kDepthColor: {  // (far - depth) / (far - near), clamped to [0, 1]
      if (!kLit) return;
      r = g = b = simd::clamp01(f.position[0] * c.grey[0] + f.position[1] * c.grey[1] +
                                f.position[2] * c.grey[2] + c.grey[3]);
      return;
    }
    default:  // kPassthrough: the interpolated colour
      return;
  }
}

// The headlight's Lambert term dot(n, L) / |n| of the unnormalised interpolated normal, without
// normalising the weights (both are scale-invariant) or interpolating colours (kUniformLit).
SR_INLINE simd::f8 shade_uniform(const ShadeConstants& c, const ShadeTriangle& s, simd::f8 b0,
                                 simd::f8 b1, simd::f8 b2) {
  using simd::f8;
  const f8 nx = b0 * s.normal[0].x + b1 * s.normal[1].x + b2 * s.normal[2].x;
  const f8 ny = b0 * s.normal[0].y + b1 * s.normal[1].y + b2 * s.normal[2].y;
  const f8 nz = b0 * s.normal[0].z + b1 * s.normal[1].z + b2 * s.normal[2].z;
  const f8 len2 = nx * nx + ny * ny + nz * nz;
  const f8 dot = b0 * c.light[0] + b1 * c.light[1] + b2 * c.light[2];
  const f8 d = dot / simd::sqrt(len2);  // NaN for a zero normal: no diffuse term
  return c.ambient + c.diffuse * (f8{} < d ? d : f8{});
}

}  // namespace sr
