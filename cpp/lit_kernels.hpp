// Lighting and texturing out of line: the parts of shading that are dear per pixel and that most
// pixels skip (the light loop, texture sampling, normal maps), compiled once per instruction set
// (lit_kernels.cpp) and called by the shading kernels through LitKernels, once per tile (the
// light pass) or per group of eight textured pixels. The kernels inline only the cheap formulas
// (shade_models.hpp), so they compile in seconds, and each of these is compiled once, not once
// per kernel.
//
// Vectors cross these calls by reference (pointers), never by value: a caller compiled for AVX2
// and a callee compiled for the generic target would disagree on how to pass an eight-lane vector.
#pragma once

#include "lighting.hpp"
#include "simd.hpp"

namespace sr {

struct Fragment;
struct ShadeConstants;
struct ShadeParams;
struct ShadeScratch;
struct TileRect;
struct TileScratch;

struct LitKernels {
  // The tile's light pass: the pixels whose triangles left their lighting to it
  // (ShadeScratch::lit_code) are lit eight at a time, whichever triangles they belong to, each
  // lane with its own draw's material and model.
  void (*light_tile)(const ShadeParams&, const TileRect&, const TileScratch&, ShadeScratch&);
  // A textured triangle's pixels that are not left to the light pass (ShadeConstants::kOutOfLine):
  // base colour r, g, b in, radiance out.
  void (*shade)(const ShadeConstants&, const Fragment&, simd::f8&, simd::f8&, simd::f8&);
  // What the light pass reads of a textured pixel: the normal (perturbed by a normal or bump
  // texture, turned toward the lit side) and the base colour times the base colour texture.
  void (*surface)(const ShadeConstants&, const Fragment&, simd::f8 (&)[3], simd::f8&, simd::f8&,
                  simd::f8&);
  // The normal output of a normal- or bump-mapped pixel (kWorkShadingNormal): the unit
  // interpolated normal in, perturbed as the shading perturbs it out.
  void (*shading_normal)(const ShadeConstants&, const Fragment&, simd::f8 (&)[3]);
};
// The kernels compiled for `isa` (lit_kernels.cpp).
const LitKernels& lit_kernels(Isa isa);

// The radiance at up to eight points given per lane, each of `count` points with its own normal,
// position and base colour: the vertex and face frequencies' per-triangle lighting. Compiled once
// for the generic target (lighting.cpp): the same bits for either instruction set's kernels.
void radiance_at(const LitInputs& in, const Material& m, Brdf brdf, const vec3* n, const vec3* p,
                 const vec3* base, int count, vec3* out);

}  // namespace sr
