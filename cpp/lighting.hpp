// Lights, materials and the reflectance models of the lit shading model, eight pixels at a time.
// The formulas (and their reasons) are python/softrast/material.py's and light.py's; `pbr` is
// pyrender's mesh.frag (GGX distribution, its Schlick-style geometric term, Schlick Fresnel,
// Lambert diffuse scaled by (1 - F)), stated beside the code.
//
// Only +, -, *, /, sqrt, comparisons and bit operations on lanes: the AVX2 and generic kernels
// give the same bits (no libm calls, whose results could differ between instruction sets; pow
// is exp2(p * log2(x)) with polynomials below).
#pragma once

#include "materials.hpp"
#include "math.hpp"
#include "shadow.hpp"
#include "simd.hpp"

#include <cstdint>
#include <cstring>

namespace sr {

// Per-pixel material values from textures (metallic-roughness, occlusion), eight lanes.
struct MaterialLanes {
  simd::f8 metallic, roughness, occlusion;
  simd::f8 specular[3];  // scales ks (phong, blinn_phong): a specular texture's rgb, else 1
};

namespace simd {

SR_INLINE f8 clamp01(f8 v) {
  const f8 one = splat(1.0f);
  const f8 c = f8{} < v ? v : f8{};
  return c < one ? c : one;
}
SR_INLINE f8 as_float(i8 v) { f8 r; std::memcpy(&r, &v, sizeof r); return r; }
SR_INLINE i8 as_int(f8 v) { i8 r; std::memcpy(&r, &v, sizeof r); return r; }

// log2(x) for x > 0 finite (x = 2^e * m, m in [sqrt(1/2), sqrt(2)): log2(m) by the atanh series
// 2/ln2 * (t + t^3/3 + ... + t^9/9), t = (m - 1) / (m + 1), |t| <= 0.172: error < 1e-9). Denormals
// are taken as 2^-126 (pow's results there are far below what 8 bits or a light can show).
SR_INLINE f8 log2_pos(f8 x) {
  const f8 tiny = splat(1.17549435e-38f);
  x = x < tiny ? tiny : x;
  i8 bits = as_int(x);
  i8 e = ((bits >> 23) & 0xff) - 127;
  f8 m = as_float((bits & 0x007fffff) | 0x3f800000);  // [1, 2)
  const i8 big = m > splat(1.41421356f);
  m = big ? m * 0.5f : m;
  e = big ? e + 1 : e;
  const f8 t = (m - 1.0f) / (m + 1.0f), t2 = t * t, t4 = t2 * t2;
  // The polynomial in t2 by Estrin's scheme (pairs, then t2, t4), not Horner's: pow is a chain
  // of dependent operations in the light loop, and this one is four multiply-adds shorter.
  const f8 series = t * ((2.0f + t2 * 0.666666667f) + t4 * ((0.4f + t2 * 0.285714286f) + t4 * 0.222222222f));
  return to_float(e) + series * 1.44269504f;  // series = ln(m)
}

// 2^y for y <= 0 (y < -126 gives 0): 2^n * 2^f, n = round(y), f in [-0.5, 0.5], 2^f by its
// Taylor series to f^7 (relative error < 2e-9).
SR_INLINE f8 exp2_neg(f8 y) {
  const i8 under = y < splat(-126.0f);
  y = under ? splat(-126.0f) : y;
  const f8 n = to_float(__builtin_convertvector(y - 0.5f, i8));  // y <= 0: rounds toward zero
  // n = trunc(y - 0.5) is round-half-down for y <= 0; f = y - n lies in [-0.5, 0.5].
  const f8 f = (y - n) * 0.693147181f, f2 = f * f, f4 = f2 * f2;
  // Estrin's scheme (as log2_pos): a chain of five dependent steps, not Horner's fourteen.
  const f8 p = ((1.0f + f) + f2 * (0.5f + f * 0.166666667f)) +
               f4 * ((0.0416666667f + f * 0.00833333333f) + f2 * (0.00138888889f + f * 0.000198412698f));
  const f8 scale = as_float((__builtin_convertvector(n, i8) + 127) << 23);
  return under ? f8{} : p * scale;
}

// x^p for x in [0, 1] and p >= 0 (0^0 = 1, as pow).
SR_INLINE f8 pow01(f8 x, f8 p) {
  const f8 r = exp2_neg(p * log2_pos(x));
  return x > f8{} ? r : (p > f8{} ? f8{} : splat(1.0f));
}

// The largest whole exponent taken by multiplying (power_n below); a larger or fractional one
// goes through pow01. k squarings and multiplies leave a relative error below k ulps times the
// exponent (about 4e-6 at 64), against pow01's 2e-7: both below what an input that is off by an
// ulp already gives the power (the exponent times an ulp).
constexpr int kMaxWholeExponent = 64;

// x^n for a whole n in [0, kMaxWholeExponent], by squaring (x^0 = 1, as pow01): a few multiplies
// instead of pow01's two polynomials, a division and its range reductions. n is the material's,
// the same for every lane: the loop branches alike for every pixel.
SR_INLINE f8 power_n(f8 x, int n) {
  f8 result = splat(1.0f);
  for (;;) {
    if (n & 1) result *= x;
    n >>= 1;
    if (n == 0) return result;
    x *= x;
  }
}

// The whole exponent p as an int, or -1 if p is fractional or above kMaxWholeExponent.
SR_INLINE int whole_exponent(float p) {
  return p >= 0.0f && p <= float(kMaxWholeExponent) && p == float(int(p)) ? int(p) : -1;
}

}  // namespace simd

// What the lit model reads of a render (per-light values are splatted per group of eight: for a
// few lights, one broadcast each costs less than keeping them per triangle).
struct LitInputs {
  const Light* lights;
  int num_lights;
  vec3 ambient_light;
  vec3 eye;          // perspective: the camera centre; orthographic: the direction toward it
  float eye_point;   // 1 for a perspective camera (v = eye - p), 0 for orthographic (v = eye)
  // The occluders, where some light casts shadows (else null: every light's visibility is 1).
  const ShadowScene* shadows = nullptr;
};

// Every light's visibility (0 or 1) at eight points p with normals n (shadow_lights, out of
// line): [8 k + i] for light k and lane i, in the calling thread's buffer. Called once before the
// light loop, so that the loop itself holds no call (across which every vector register would
// have to be saved). kFacing: cast only where n faces the light (the models that add nothing
// from behind).
template <bool kFacing>
SR_INLINE const float* light_visibilities(const LitInputs& in, const simd::f8 (&n)[3],
                                          const simd::f8 (&p)[3], const simd::i8* active) {
  alignas(32) float x[8], y[8], z[8], nx[8], ny[8], nz[8];
  simd::store(x, p[0]);
  simd::store(y, p[1]);
  simd::store(z, p[2]);
  simd::store(nx, n[0]);
  simd::store(ny, n[1]);
  simd::store(nz, n[2]);
  uint32_t mask = 0xffu;
  if (active) {
    mask = 0;
    for (int i = 0; i < 8; ++i) mask |= uint32_t((*active)[i] != 0) << i;
  }
  return shadow_lights(*in.shadows, in.lights, in.num_lights, x, y, z, nx, ny, nz, kFacing, mask);
}

// Radiance of eight pixels: unit normal n (toward the side being lit), world position p, base
// colour base (kd / ka where the material says so), material m, summed over the lights.
// Compiled per reflectance model B (Lambert, Phong, BlinnPhong or Pbr) and per whether it has a
// specular term, so that only that model's values are live in the light loop (one loop for all
// models kept some 27 vectors live, and spilled). kPositions: a light or term reads p.
// kLanes: per-pixel metallic, roughness, ambient occlusion and ks scale from `lanes` (textures; compiled
// out of line only, material_maps.cpp), else the material's scalars.
// `active`: the lanes that are shaded (null: all), where a shadowed light casts its rays.
template <Brdf B, bool kSpecular, bool kPositions, bool kLanes = false>
SR_INLINE void lit_radiance(const LitInputs& in, const Material& m, const simd::f8 (&n)[3],
                            const simd::f8 (&p)[3], const simd::f8 (&base)[3],
                            simd::f8 (&out)[3], const MaterialLanes* lanes = nullptr,
                            const simd::i8* active = nullptr) {
  using namespace simd;
  constexpr bool kPbr = B == Brdf::Pbr;
  constexpr bool kView = kPositions && (kSpecular || kPbr);  // reads the view vector
  f8 kd[3];
  for (int c = 0; c < 3; ++c) {
    kd[c] = m.kd_is_base ? base[c] : splat(m.kd[c]);
    // pbr: the base colour times the ambient light, as pyrender (ka is not read).
    const f8 ka = kPbr ? base[c] : (m.ka_is_kd ? kd[c] : splat(m.ka[c]));
    if constexpr (kLanes)
      out[c] = ka * in.ambient_light[c] * lanes->occlusion + m.emissive[c];
    else
      out[c] = ka * in.ambient_light[c] + m.emissive[c];
  }
  f8 v[3] = {};
  if constexpr (kView) {  // unit vector toward the eye
    for (int c = 0; c < 3; ++c) v[c] = in.eye[c] - p[c] * in.eye_point;
    const f8 r = 1.0f / simd::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int c = 0; c < 3; ++c) v[c] *= r;
  }
  const int whole = whole_exponent(m.shininess);  // chosen once: multiplied out, or exp2/log2
  // Shadowed lights' visibility, before the loop (null: no light casts shadows).
  const float* vis = nullptr;
  if (kPositions && in.shadows) vis = light_visibilities<!kPbr>(in, n, p, active);
  for (int k = 0; k < in.num_lights; ++k) {
    const Light& light = in.lights[k];
    f8 l[3], att = splat(1.0f);
    if (light.kind == LightKind::Directional || !kPositions) {
      for (int c = 0; c < 3; ++c) l[c] = splat(-light.direction[c]);
    } else {
      for (int c = 0; c < 3; ++c) l[c] = light.position[c] - p[c];
      const f8 r2 = l[0] * l[0] + l[1] * l[1] + l[2] * l[2];
      const f8 inv_r = 1.0f / simd::sqrt(r2);
      for (int c = 0; c < 3; ++c) l[c] *= inv_r;
      if (light.inverse_square) att = inv_r * inv_r;  // 1 / r^2 without a second division
      if (light.kind == LightKind::Spot) {
        const f8 cd = -(light.direction[0] * l[0] + light.direction[1] * l[1] + light.direction[2] * l[2]);
        const f8 t = clamp01(clamp01(cd) * light.cone_scale + light.cone_offset);
        att *= t * t;
      }
      if constexpr (kPbr) {
        // A point or spot light exactly at the point (r = 0) lights nothing there: l = 0 and
        // no attenuation keep every pbr term finite (the other models skip such a light: n.l
        // is NaN there, never > 0).
        const i8 apart = r2 > 0.0f;
        for (int c = 0; c < 3; ++c) l[c] = apart ? l[c] : f8{};
        att = apart ? att : f8{};
      }
    }
    const f8 ndl = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
    if constexpr (kPbr) {
      if (vis) att *= simd::load<f8>(vis + 8 * k);
      // pyrender 0.1.45's mesh.frag (docs/pbr_notes.md): r = clamp(roughness, 0.04, 1), a = r^2;
      // h = normalize(l + v); nl = clamp(n.l, 0.001, 1) (a light behind the surface still adds
      // a little, as pyrender's does); nv = clamp(|n.v|, 0.001, 1); nh, vh clamped to [0, 1];
      // F = f0 + (1 - f0) (1 - vh)^5, f0 = mix(0.04, base, metallic); k = (r + 1)^2 / 8,
      // G = nl nv / ((nl (1 - k) + k)(nv (1 - k) + k)); D = a^2 / (pi (nh^2 (a^2 - 1) + 1)^2);
      // radiance += nl I ((1 - F) c_diff / pi + F G D / (4 nl nv + 0.001)),
      // c_diff = base (1 - 0.04) (1 - metallic). G D / (4 nl nv + 0.001) is taken as one quotient,
      // nl nv a^2 / ((nl (1 - k) + k)(nv (1 - k) + k) pi f^2 (4 nl nv + 0.001)): one division.
      // h is never formed: with l and v unit, |l + v|^2 = 2 + 2 l.v, n.h = (n.l + n.v) / |l + v|
      // and v.h = (1 + l.v) / |l + v| (l = -v: 0 / 0, and nh = vh = 0 below).
      const f8 lv = l[0] * v[0] + l[1] * v[1] + l[2] * v[2];
      const f8 hr = 1.0f / simd::sqrt(2.0f + 2.0f * lv);
      const f8 lo = splat(0.001f), one = splat(1.0f);
      const f8 nl = ndl > lo ? (one < ndl ? one : ndl) : lo;  // NaN -> 0.001
      const f8 n_v = n[0] * v[0] + n[1] * v[1] + n[2] * v[2];
      f8 nv = n_v < f8{} ? -n_v : n_v;
      nv = nv > lo ? (one < nv ? one : nv) : lo;
      const f8 nh = clamp01((ndl + n_v) * hr);
      const f8 vh = clamp01((1.0f + lv) * hr);
      f8 spec_common, diffuse_scale, metallic;
      if constexpr (kLanes) {  // the same formulas per lane
        const f8 r0 = lanes->roughness, floor = splat(0.04f);
        const f8 rough = r0 > floor ? r0 : floor;  // NaN -> 0.04
        const f8 kk = (rough + 1.0f) * (rough + 1.0f) * 0.125f;
        const f8 a2 = rough * rough * (rough * rough);
        const f8 f = nh * nh * (a2 - 1.0f) + 1.0f;
        spec_common = nl * nv * a2 / ((nl * (1.0f - kk) + kk) * (nv * (1.0f - kk) + kk) *
                                      (3.14159265f * f * f) * (4.0f * nl * nv + 0.001f));
        metallic = lanes->metallic;
        diffuse_scale = 0.96f * (1.0f - metallic) * 0.318309886f;
      } else {
        const float rough = m.roughness > 0.04f ? m.roughness : 0.04f;
        const float kk = (rough + 1.0f) * (rough + 1.0f) * 0.125f;
        const float a2 = rough * rough * (rough * rough);
        const f8 f = nh * nh * (a2 - 1.0f) + 1.0f;
        spec_common = nl * nv * a2 / ((nl * (1.0f - kk) + kk) * (nv * (1.0f - kk) + kk) *
                                      (3.14159265f * f * f) * (4.0f * nl * nv + 0.001f));
        metallic = splat(m.metallic);
        diffuse_scale = splat(0.96f * (1.0f - m.metallic) * 0.318309886f);
      }
      const f8 s = one - vh, s2 = s * s, s5 = s2 * s2 * s;
      const f8 lit = nl * att;
      for (int c = 0; c < 3; ++c) {
        const f8 f0 = 0.04f + (base[c] - 0.04f) * metallic;
        const f8 fr = f0 + (1.0f - f0) * s5;
        out[c] += lit * light.radiance[c] * ((1.0f - fr) * (base[c] * diffuse_scale) + fr * spec_common);
      }
      continue;
    }
    // Lights behind the surface add nothing: a group that no light reaches skips the light.
    const i8 front = ndl > f8{};
    if (!any(front)) continue;
    if (vis) {
      const f8 visible = simd::load<f8>(vis + 8 * k);
      if (!any(visible > f8{})) continue;  // (every lane in shadow)
      att *= visible;
    }
    const f8 diffuse = (front ? ndl : f8{}) * att;
    for (int c = 0; c < 3; ++c) out[c] += kd[c] * (diffuse * light.radiance[c]);
    if constexpr (kSpecular) {
      f8 power;
      if constexpr (B == Brdf::Phong) {  // r = 2 (n.l) n - l, (r.v)^p
        f8 rv = f8{};
        for (int c = 0; c < 3; ++c) rv += (2.0f * ndl * n[c] - l[c]) * v[c];
        const f8 x = clamp01(rv);
        power = whole >= 0 ? power_n(x, whole) : pow01(x, splat(m.shininess));
      } else {
        // h = (l + v) / |l + v|, (n.h)^p, taken as ((n.(l + v))^2 / |l + v|^2)^(p / 2) where
        // n.(l + v) > 0 (else 0): no square root before the chain of pow.
        f8 h[3];
        for (int c = 0; c < 3; ++c) h[c] = l[c] + v[c];
        const f8 len2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
        const f8 nh = n[0] * h[0] + n[1] * h[1] + n[2] * h[2];
        const f8 cos2 = clamp01(nh > f8{} ? nh * nh / len2 : f8{});
        // A whole exponent p: cos2^(p div 2), times sqrt(cos2) (= n.h) where p is odd.
        if (whole >= 0) {
          power = power_n(cos2, whole >> 1);
          if (whole & 1) power *= simd::sqrt(cos2);
        } else {
          power = pow01(cos2, splat(0.5f * m.shininess));
        }
      }
      const f8 spec = front ? power * att : f8{};
      if constexpr (kLanes)
        for (int c = 0; c < 3; ++c) out[c] += (spec * light.radiance[c]) * (m.ks[c] * lanes->specular[c]);
      else
        for (int c = 0; c < 3; ++c) out[c] += (spec * light.radiance[c]) * m.ks[c];
    }
  }
}

// lit_radiance for the reflectance model `brdf` (Lambert, Phong, BlinnPhong or Pbr): one branch
// per call on a per-triangle value. Without positions only Lambert can be asked for (LitModel
// reads positions for every view-dependent term), so that is the one variant compiled for it:
// each variant is inlined into every shading kernel, and their count is the compile time.
template <bool kPositions>
SR_INLINE void lit_radiance(const LitInputs& in, const Material& m, Brdf brdf,
                            const simd::f8 (&n)[3], const simd::f8 (&p)[3],
                            const simd::f8 (&base)[3], simd::f8 (&out)[3],
                            const simd::i8* active = nullptr) {
  if constexpr (kPositions) {
    const bool specular = m.ks.x > 0.0f || m.ks.y > 0.0f || m.ks.z > 0.0f;
    switch (brdf) {
      case Brdf::Pbr: return lit_radiance<Brdf::Pbr, false, true>(in, m, n, p, base, out, nullptr, active);
      case Brdf::Phong:
        if (specular)
          return lit_radiance<Brdf::Phong, true, true>(in, m, n, p, base, out, nullptr, active);
        break;
      case Brdf::BlinnPhong:
        if (specular)
          return lit_radiance<Brdf::BlinnPhong, true, true>(in, m, n, p, base, out, nullptr, active);
        break;
      default: break;
    }
  }
  lit_radiance<Brdf::Lambert, false, kPositions>(in, m, n, p, base, out, nullptr, active);
}

// lit_radiance with per-pixel material values (kLanes), every model, positions read; out of
// line and compiled for the generic target once (material_maps.cpp): the same bits for either
// instruction set's kernels, and no more inlined light loops. Arrays, not vectors, cross the
// call (the callers are compiled for AVX2 or not).
void lit_radiance_lanes(const LitInputs& in, const Material& m, Brdf brdf, const simd::f8* n,
                        const simd::f8* p, const simd::f8* base, const MaterialLanes& lanes,
                        simd::f8* out, const int32_t* active);

}  // namespace sr
