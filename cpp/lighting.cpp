// The lit model's radiance with per-pixel material values (metallic-roughness and occlusion
// textures): lighting.hpp's lit_radiance with kLanes, compiled once, for the generic target, and
// called by both instruction sets' shading kernels (the same bits either way).
#include "lighting.hpp"

namespace sr {

void lit_radiance_lanes(const LitInputs& in, const Material& m, Brdf brdf, const simd::f8* n,
                        const simd::f8* p, const simd::f8* base, const MaterialLanes& lanes,
                        simd::f8* out) {
  using simd::f8;
  const f8 nn[3] = {n[0], n[1], n[2]}, pp[3] = {p[0], p[1], p[2]}, bb[3] = {base[0], base[1], base[2]};
  f8 o[3];
  const bool specular = m.ks.x > 0.0f || m.ks.y > 0.0f || m.ks.z > 0.0f;
  switch (brdf) {
    case Brdf::Pbr: lit_radiance<Brdf::Pbr, false, true, true>(in, m, nn, pp, bb, o, &lanes); break;
    case Brdf::Phong:
      if (specular) {
        lit_radiance<Brdf::Phong, true, true, true>(in, m, nn, pp, bb, o, &lanes);
        break;
      }
      [[fallthrough]];
    case Brdf::BlinnPhong:
      if (specular && brdf == Brdf::BlinnPhong) {
        lit_radiance<Brdf::BlinnPhong, true, true, true>(in, m, nn, pp, bb, o, &lanes);
        break;
      }
      [[fallthrough]];
    default: lit_radiance<Brdf::Lambert, false, true, true>(in, m, nn, pp, bb, o, &lanes); break;
  }
  for (int c = 0; c < 3; ++c) out[c] = o[c];
}

}  // namespace sr
