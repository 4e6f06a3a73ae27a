// Shading of a visible triangle, per triangle: classify (its colour kind and what its pixels
// read) and its per-pixel constants. Scalar code, compiled once (shade_models.hpp).
#include "shade_models.hpp"

#include "lit_kernels.hpp"

#include <algorithm>
#include <cmath>

namespace sr {

namespace {

vec3 unit_or_zero(vec3 v) {
  const float len2 = glm::dot(v, v);
  return len2 > 0.0f ? v * (1.0f / std::sqrt(len2)) : vec3(0.0f);
}

// Does the radiance depend on the position (point lights, the view vector, or shadows)?
bool reads_position(const ShadeInputs& in, const Material& m, Brdf brdf) {
  if (brdf == Brdf::Pbr || in.lit.shadows) return true;  // (shadow rays start at the point)
  if ((brdf == Brdf::Phong || brdf == Brdf::BlinnPhong) &&
      (m.ks.x > 0.0f || m.ks.y > 0.0f || m.ks.z > 0.0f))
    return true;
  for (int k = 0; k < in.lit.num_lights; ++k)
    if (in.lit.lights[k].kind != LightKind::Directional) return true;
  return false;
}

// The triangle's tangent frame from its positions and uvs (per face, in world space):
// dp = T du + B dv over its two edges. Mirrored uvs flip the bitangent (handedness).
void tangent_frame(ShadeTriangle& s) {
  const vec3 e1 = s.position[1] - s.position[0], e2 = s.position[2] - s.position[0];
  const float du1 = s.attr[1][0] - s.attr[0][0], dv1 = s.attr[1][1] - s.attr[0][1];
  const float du2 = s.attr[2][0] - s.attr[0][0], dv2 = s.attr[2][1] - s.attr[0][1];
  const float det = du1 * dv2 - du2 * dv1;
  const vec3 t = (e1 * dv2 - e2 * dv1), bt = (e2 * du1 - e1 * du2);
  const vec3 n = s.normal[0] + s.normal[1] + s.normal[2];  // the visible side
  const float sign = det < 0.0f ? -1.0f : 1.0f;   // t, bt above are det * (T, B)
  s.tangent = det != 0.0f && std::isfinite(det) ? unit_or_zero(t * sign) : vec3(0.0f);
  s.handedness = glm::dot(glm::cross(n, t * sign), bt * sign) < 0.0f ? -1.0f : 1.0f;
}

// A textured material's triangle: its colour always varies per pixel (the textures are sampled
// there). The vertex and face frequencies light the vertices or the face with the untextured base
// colour and modulate the result per pixel by the base colour texture (OpenGL's fixed-function
// GL_MODULATE), plus the emissive texture; a normal texture is read at the pixel frequency only.
void classify_textured(const ShadeInputs& in, bool uniform_color, ShadeTriangle& s) {
  const Material& m = *s.material;
  const Brdf brdf = s.brdf;
  s.color_kind = ShadeTriangle::kVaryingColor;
  s.reads = ShadeTriangle::kReadUv | ShadeTriangle::kReadUvDerivs;
  if (brdf == Brdf::Unlit) {
    s.passthrough = true;
    return;
  }
  const vec3 side(s.side);
  if (brdf != Brdf::Normal && in.frequency != Frequency::Pixel) {
    s.passthrough = true;
    if (in.frequency == Frequency::Face) {
      const vec3 p = (s.position[0] + s.position[1] + s.position[2]) * (1.0f / 3.0f);
      const vec3 base = uniform_color ? s.color[0] : (s.color[0] + s.color[1] + s.color[2]) * (1.0f / 3.0f);
      const vec3 ns = s.face_normal * side;
      vec3 rgb;
      radiance_at(in.lit, m, brdf, &ns, &p, &base, 1, &rgb);
      s.color[0] = s.color[1] = s.color[2] = rgb;
    } else {
      vec3 n[3], base[3];
      for (int k = 0; k < 3; ++k) {
        n[k] = unit_or_zero(s.normal[k]) * side;
        base[k] = uniform_color ? s.color[0] : s.color[k];
      }
      radiance_at(in.lit, m, brdf, n, s.position, base, 3, s.color);
    }
    return;
  }
  if (brdf == Brdf::Normal && in.frequency != Frequency::Pixel) {
    s.passthrough = true;
    for (int k = 0; k < 3; ++k)
      s.color[k] = in.frequency == Frequency::Face ? s.face_normal * 0.5f + 0.5f
                                                   : unit_or_zero(s.normal[k]) * 0.5f + 0.5f;
    return;
  }
  s.reads |= ShadeTriangle::kReadNormal;
  if (brdf != Brdf::Normal && (reads_position(in, m, brdf) || m.material_maps()))
    s.reads |= ShadeTriangle::kReadPosition;
  if (m.normal_texture || m.bump_texture) {
    s.normal_map = true;
    tangent_frame(s);
  }
}

// Every other draw: its material and reflectance model, summed over the render's lights, at the
// render's frequency (lighting.hpp holds the formulas); textured unlit and normal draws too.
void classify_material(const ShadeInputs& in, bool uniform_color, ShadeTriangle& s) {
  const Material& m = *s.material;
  const Brdf brdf = s.brdf;
  s.passthrough = false;
  s.side = s.back_facing && !m.double_sided ? -1.0f : 1.0f;
  s.normal_map = false;
  s.reads = 0;
  if (m.textured()) {
    classify_textured(in, uniform_color, s);
    return;
  }
  if (brdf == Brdf::Unlit) {
    classify_unlit(uniform_color, s);
    return;
  }
  if (brdf == Brdf::Normal) {  // (n + 1) / 2 at the render's frequency
    if (in.frequency == Frequency::Face || s.one_normal) {
      s.color_kind = ShadeTriangle::kConstantColor;
      s.rgb = (in.frequency == Frequency::Face ? s.face_normal : s.unit_normal) * 0.5f + 0.5f;
    } else if (in.frequency == Frequency::Vertex) {
      s.color_kind = ShadeTriangle::kVaryingColor;
      for (int k = 0; k < 3; ++k) s.color[k] = unit_or_zero(s.normal[k]) * 0.5f + 0.5f;
      s.passthrough = true;
    } else {
      s.color_kind = ShadeTriangle::kVaryingColor;
      s.reads = ShadeTriangle::kReadNormal;
    }
    return;
  }
  const bool position = reads_position(in, m, brdf);
  const vec3 side(s.side);
  if (in.frequency == Frequency::Face ||
      (uniform_color && s.one_normal && !position)) {  // one colour for the whole face
    const vec3 n = in.frequency == Frequency::Face ? s.face_normal : s.unit_normal;
    const vec3 p = (s.position[0] + s.position[1] + s.position[2]) * (1.0f / 3.0f);
    const vec3 base = uniform_color ? s.color[0] : (s.color[0] + s.color[1] + s.color[2]) * (1.0f / 3.0f);
    const vec3 ns = n * side;
    radiance_at(in.lit, m, brdf, &ns, &p, &base, 1, &s.rgb);
    s.color_kind = ShadeTriangle::kConstantColor;
    return;
  }
  s.color_kind = ShadeTriangle::kVaryingColor;
  if (in.frequency == Frequency::Vertex) {  // Gouraud: light the vertices, interpolate colour
    vec3 n[3], base[3];
    for (int k = 0; k < 3; ++k) {
      n[k] = unit_or_zero(s.normal[k]) * side;
      base[k] = uniform_color ? s.color[0] : s.color[k];
    }
    radiance_at(in.lit, m, brdf, n, s.position, base, 3, s.color);
    s.passthrough = true;
    if (s.color[0] == s.color[1] && s.color[0] == s.color[2]) {
      s.color_kind = ShadeTriangle::kConstantColor;
      s.rgb = s.color[0];
    }
    return;
  }
  s.reads = ShadeTriangle::kReadNormal | (position ? ShadeTriangle::kReadPosition : 0);
}

}  // namespace

void classify_lit(const ShadeInputs& in, bool uniform_color, ShadeTriangle& s) {
  s.normal_map = false;
  s.side = 1.0f;
  s.tangent = vec3(0.0f);
  s.handedness = 1.0f;
  classify_material(in, uniform_color, s);
  // The normal output with the normal or bump map applied (render(normal_kind="shading")): the
  // tangent frame even where the colour does not read it (unlit, or no colour output).
  const Material& m = *s.material;
  if (in.shading_normals && (m.normal_texture || m.bump_texture)) {
    if (!s.normal_map) tangent_frame(s);
    s.normal_out_map = true;
  }
  // Only the formulas that start from the base colour read it: not the normal as a colour.
  if (s.color_kind == ShadeTriangle::kVaryingColor && (s.brdf != Brdf::Normal || s.passthrough))
    s.reads |= ShadeTriangle::kReadColor;
}

void make_lit_constants(const ShadeInputs& in, const LitKernels* kernels, const ShadeTriangle& s,
                        ShadeConstants& c) {
  const Material& m = *s.material;
  c.in = &in.lit;
  c.material = &m;
  c.kernels = kernels;
  c.brdf = s.brdf;
  c.passthrough = s.passthrough;
  c.positions = (s.reads & ShadeTriangle::kReadPosition) != 0;
  c.textured = (s.reads & ShadeTriangle::kReadUv) != 0;
  c.normal_map = s.normal_map;
  c.side = simd::splat(s.side);
  c.tangent = s.tangent;
  c.handedness = s.handedness;
  c.op = c.textured          ? ShadeConstants::kOutOfLine
         : c.passthrough     ? ShadeConstants::kPassthrough
         : s.brdf == Brdf::Normal ? ShadeConstants::kNormalColor
                                  : ShadeConstants::kOutOfLine;
  const bool lit = s.color_kind == ShadeTriangle::kVaryingColor && !c.passthrough &&
                   s.brdf != Brdf::Normal && s.brdf != Brdf::Unlit;
  const bool after = c.textured && (m.material_maps() || m.emissive_texture);
  c.raw_normal = lit && !c.textured;
  c.code = lit && !after ? int32_t(4 * (s.draw + 1) + (c.raw_normal ? 2 : 0) + (c.positions ? 1 : 0))
                         : 0;
  if (c.textured) {
    const auto pick = [&](const Texture* t) {
      return in.texture_filter != kNoFilterOverride ? TextureFilter(in.texture_filter)
             : t ? t->filter : TextureFilter::Nearest;
    };
    c.base_filter = pick(m.base_color_texture);
    c.emissive_filter = pick(m.emissive_texture);
    c.normal_filter = pick(m.normal_texture);
    c.mr_filter = pick(m.metallic_roughness_texture);
    c.occlusion_filter = pick(m.occlusion_texture);
    c.bump_filter = pick(m.bump_texture);
    c.specular_filter = pick(m.specular_texture);
  }
}

}  // namespace sr
