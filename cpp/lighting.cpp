// The lit radiance out of line, compiled once for the generic target and called by either
// instruction set's kernels (the same bits either way): with per-pixel material values
// (metallic-roughness and occlusion textures: lighting.hpp's lit_radiance with kLanes), and at
// given points (the vertex and face frequencies, lit_kernels.hpp).
#include "lighting.hpp"

#include "lit_kernels.hpp"

namespace sr {

void radiance_at(const LitInputs& in, const Material& m, Brdf brdf, const vec3* n, const vec3* p,
                 const vec3* base, int count, vec3* out) {
  simd::f8 nl[3] = {}, pl[3] = {}, bl[3] = {}, o[3];
  for (int i = 0; i < count; ++i)
    for (int c = 0; c < 3; ++c) {
      nl[c][i] = n[i][c];
      pl[c][i] = p[i][c];
      bl[c][i] = base[i][c];
    }
  simd::i8 active = {};  // (the points given: their shadow rays only)
  for (int i = 0; i < count; ++i) active[i] = -1;
  lit_radiance<true>(in, m, brdf, nl, pl, bl, o, &active);
  for (int i = 0; i < count; ++i) out[i] = vec3(o[0][i], o[1][i], o[2][i]);
}

void lit_radiance_lanes(const LitInputs& in, const Material& m, Brdf brdf, const simd::f8* n,
                        const simd::f8* p, const simd::f8* base, const MaterialLanes& lanes,
                        simd::f8* out, const int32_t* active) {
  using simd::f8;
  const simd::i8 shaded = simd::load<simd::i8>(active);
  const f8 nn[3] = {n[0], n[1], n[2]}, pp[3] = {p[0], p[1], p[2]}, bb[3] = {base[0], base[1], base[2]};
  f8 o[3];
  const bool specular = m.ks.x > 0.0f || m.ks.y > 0.0f || m.ks.z > 0.0f;
  switch (brdf) {
    case Brdf::Pbr: lit_radiance<Brdf::Pbr, false, true, true>(in, m, nn, pp, bb, o, &lanes, &shaded); break;
    case Brdf::Phong:
      if (specular) {
        lit_radiance<Brdf::Phong, true, true, true>(in, m, nn, pp, bb, o, &lanes, &shaded);
        break;
      }
      [[fallthrough]];
    case Brdf::BlinnPhong:
      if (specular && brdf == Brdf::BlinnPhong) {
        lit_radiance<Brdf::BlinnPhong, true, true, true>(in, m, nn, pp, bb, o, &lanes, &shaded);
        break;
      }
      [[fallthrough]];
    default: lit_radiance<Brdf::Lambert, false, true, true>(in, m, nn, pp, bb, o, &lanes, &shaded); break;
  }
  for (int c = 0; c < 3; ++c) out[c] = o[c];
}

}  // namespace sr
