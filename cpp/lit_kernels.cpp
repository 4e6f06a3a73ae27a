// Lighting and texturing out of line, compiled once per instruction set (lit_kernels.hpp).
#include "lit_kernels.hpp"

#include "dispatch.hpp"
#include "shade.hpp"
#include "shade_models.hpp"

namespace sr {

namespace {

using simd::f8;

// n / |n| per lane, zero where n is zero.
SR_INLINE void normalize(f8& nx, f8& ny, f8& nz) {
  const f8 len2 = nx * nx + ny * ny + nz * nz;
  const f8 r = 1.0f / simd::sqrt(len2);
  const simd::i8 nonzero = len2 > 0.0f;
  nx = nonzero ? nx * r : f8{};
  ny = nonzero ? ny * r : f8{};
  nz = nonzero ? nz * r : f8{};
}

// Samples `tex` at the fragment's uvs (plus du, dv) into out[0..3] (lanes of f.mine).
SR_INLINE void sample(const Texture& tex, TextureFilter filter, const Fragment& f, f8 (&out)[4],
                      float du = 0.0f, float dv = 0.0f) {
  alignas(32) float u[8], v[8], ux[8], vx[8], uy[8], vy[8], o[4][8] = {};
  simd::store(u, f.attr[0] + du); simd::store(v, f.attr[1] + dv);
  simd::store(ux, f.attr_dx[0]); simd::store(vx, f.attr_dx[1]);
  simd::store(uy, f.attr_dy[0]); simd::store(vy, f.attr_dy[1]);
  uint32_t mask = 0;
  for (int i = 0; i < 8; ++i) mask |= uint32_t(f.mine[i] != 0) << i;
  sample_texture8(tex, filter, u, v, ux, vx, uy, vy, mask, o);
  for (int c = 0; c < 4; ++c) out[c] = simd::load<f8>(o[c]);
}

// The normal texture's tangent-space normal (2 rgb - 1, x and y scaled by normal_scale, y
// negated for a DirectX-style map) in the frame (t, b, n): t the triangle's tangent made
// orthogonal to the pixel's normal n, b = handedness n x t. Where the frame is degenerate (no
// tangent, a zero normal) n is kept.
// A bump texture instead (the course notes): heights h at the pixel's uv and one texel
// further along u and along v, dU = bump_scale (h(u + 1/w) - h), dV = bump_scale (h(v + 1/h) - h),
// and the tangent-space normal (-dU, -dV, 1) in the same frame.
SR_INLINE void normal_map(const ShadeConstants& c, const Fragment& f, f8 (&n)[3]) {
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

SR_INLINE void add_emissive(const ShadeConstants& c, const Fragment& f, f8& r, f8& g, f8& b) {
  if (!c.material->emissive_texture) return;
  f8 tex[4];
  sample(*c.material->emissive_texture, c.emissive_filter, f, tex);
  const vec3 e = c.material->emissive_factor;
  r += tex[0] * e.x; g += tex[1] * e.y; b += tex[2] * e.z;
}

// Radiance with per-pixel metallic, roughness (glTF: the factors times the texture's blue and
// green), ambient occlusion (ambient times 1 + strength (red - 1)) and specular scale (ks times
// the specular texture's rgb).
SR_INLINE void material_maps(const ShadeConstants& c, const Fragment& f, const f8 (&n)[3],
                             const f8 (&base)[3], f8 (&out)[3]) {
  const Material& m = *c.material;
  MaterialLanes lanes{simd::splat(m.metallic), simd::splat(m.roughness), simd::splat(1.0f),
                      {simd::splat(1.0f), simd::splat(1.0f), simd::splat(1.0f)}};
  if (m.metallic_roughness_texture) {
    f8 tex[4];
    sample(*m.metallic_roughness_texture, c.mr_filter, f, tex);
    lanes.roughness = tex[1] * m.roughness;
    lanes.metallic = tex[2] * m.metallic;
  }
  if (m.occlusion_texture) {
    f8 tex[4];
    sample(*m.occlusion_texture, c.occlusion_filter, f, tex);
    lanes.occlusion = 1.0f + (tex[0] - 1.0f) * m.occlusion_strength;
  }
  if (m.specular_texture) {
    f8 tex[4];
    sample(*m.specular_texture, c.specular_filter, f, tex);
    for (int k = 0; k < 3; ++k) lanes.specular[k] = tex[k];
  }
  alignas(32) int32_t active[8];
  simd::store(active, f.mine);
  lit_radiance_lanes(*c.in, m, c.brdf, n, f.position, base, lanes, out, active);
}

struct TexturedSurface {
  SR_INLINE static void run(const ShadeConstants& c, const Fragment& f, f8 (&n)[3], f8& r,
                            f8& g, f8& b) {
    if (c.normal_map) normal_map(c, f, n);
    if (c.material->base_color_texture) {
      f8 tex[4];
      sample(*c.material->base_color_texture, c.base_filter, f, tex);
      r *= tex[0]; g *= tex[1]; b *= tex[2];
    }
  }
};

struct TexturedShade {
  SR_INLINE static void run(const ShadeConstants& c, const Fragment& f, f8& r, f8& g, f8& b) {
    f8 n[3] = {f.normal[0], f.normal[1], f.normal[2]};
    if (c.normal_map) normal_map(c, f, n);
    if (c.material->base_color_texture && c.brdf != Brdf::Normal) {
      f8 tex[4];
      sample(*c.material->base_color_texture, c.base_filter, f, tex);
      r *= tex[0]; g *= tex[1]; b *= tex[2];
    }
    if (c.passthrough) {
      if (c.brdf != Brdf::Unlit && c.brdf != Brdf::Normal) add_emissive(c, f, r, g, b);
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
    if (c.material->material_maps())
      material_maps(c, f, n, base, out);
    else if (c.positions)
      lit_radiance<true>(*c.in, *c.material, c.brdf, n, f.position, base, out, &f.mine);
    else
      lit_radiance<false>(*c.in, *c.material, c.brdf, n, f.position, base, out, &f.mine);
    r = out[0];
    g = out[1];
    b = out[2];
    add_emissive(c, f, r, g, b);
  }
};

struct ShadingNormal {
  SR_INLINE static void run(const ShadeConstants& c, const Fragment& f, f8 (&n)[3]) {
    normal_map(c, f, n);
  }
};

struct LightTile {
  SR_INLINE static void run(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                            ShadeScratch& out) {
    using simd::i8;
    using simd::kLanes;
    if (!out.lit_pending) return;
    out.lit_pending = false;
    const i8 lane = simd::lane_index(), none = simd::splat(int32_t(kNoTriangle));
    const int width = rect.x1 - rect.x0;
    for (int y = rect.y0; y < rect.y1; ++y) {
      const int row = (y - rect.y0) * kTileSizePx;
      for (int x = 0; x < width; x += kLanes) {
        const int i = row + x;
        const i8 code = simd::load<i8>(out.lit_code + i);
        i8 pending = (code != 0) & (simd::load<i8>(raster.visible + i) != none) & (lane < width - x);
        if (!simd::any(pending)) continue;
        f8 n[3], position[3], base[3], rgb[3];
        for (int k = 0; k < 3; ++k) {
          n[k] = simd::load<f8>(out.lit_normal[k] + i);
          position[k] = simd::load<f8>(out.lit_position[k] + i);
          base[k] = rgb[k] = simd::load<f8>(out.rgb[k] + i);
        }
        const i8 raw = pending & ((code & 2) != 0);  // normals left to normalise here
        if (simd::any(raw)) {
          f8 u[3] = {n[0], n[1], n[2]};
          normalize(u[0], u[1], u[2]);
          for (int k = 0; k < 3; ++k) n[k] = raw ? u[k] : n[k];
        }
        do {  // one draw's lanes at a time (one pass but at a material's edge)
          int32_t first = 0;
          for (int l = 0; l < kLanes; ++l)
            if (pending[l]) { first = code[l]; break; }
          const i8 mine = pending & (code == first);
          const ShadeDraw& d = p.draws[(first >> 2) - 1];
          f8 o[3];
          if (first & 1)
            lit_radiance<true>(p.in.lit, d.material, d.brdf, n, position, base, o, &mine);
          else
            lit_radiance<false>(p.in.lit, d.material, d.brdf, n, position, base, o, &mine);
          for (int k = 0; k < 3; ++k) rgb[k] = mine ? o[k] : rgb[k];
          pending = pending & ~mine;
        } while (simd::any(pending));
        for (int k = 0; k < 3; ++k) simd::store(out.rgb[k] + i, rgb[k]);
      }
    }
  }
};

using LightTileFn = decltype(LitKernels::light_tile);
using ShadeFn = decltype(LitKernels::shade);
using SurfaceFn = decltype(LitKernels::surface);
using ShadingNormalFn = decltype(LitKernels::shading_normal);

template <typename K, typename Fn>
using Kernel = dispatch::IsaKernel<K, Fn>;

}  // namespace

const LitKernels& lit_kernels(Isa isa) {
#if SR_X86
  static const LitKernels avx2{Kernel<LightTile, LightTileFn>::avx2,
                               Kernel<TexturedShade, ShadeFn>::avx2,
                               Kernel<TexturedSurface, SurfaceFn>::avx2,
                               Kernel<ShadingNormal, ShadingNormalFn>::avx2};
  if (isa == Isa::Avx2) return avx2;
#endif
  (void)isa;
  static const LitKernels generic{Kernel<LightTile, LightTileFn>::generic,
                                  Kernel<TexturedShade, ShadeFn>::generic,
                                  Kernel<TexturedSurface, SurfaceFn>::generic,
                                  Kernel<ShadingNormal, ShadingNormalFn>::generic};
  return generic;
}

}  // namespace sr
