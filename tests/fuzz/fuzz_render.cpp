// libFuzzer target over the C++ core: MeshData::validate + Renderer::render on decoded input.
// Built and run by .ci/fuzz (clang, -fsanitize=fuzzer,address,undefined); seeds come from
// tests/fuzz/make_corpus.py, which writes the same byte format this file decodes.
//
// Input format (little-endian; a read past the end yields zero bytes, so every input decodes):
//   u8 width-1, u8 height-1, u8 threads (1 + t % 3), u8 outputs (raw bits: 0 is
//   invalid), u8 cull % 3, u8 shading % kNumShadings, u8 flags (bit 0 orthographic, bit 1 re-render with
//   another thread count and compare), 3 x F background, F ambient,
//   camera: M view, P proj, D near, D far,
//   mesh: u8 vertices, vertices x 3 F, u8 faces, faces x 3 I, then normals, colors, uvs each as
//   u8 mode (0 absent, 1 one per vertex, 2 one too many, 3 one too few) and their values,
//   u8 draws % 4, per draw: M model, i32 instance id, 4 x F colour,
//   then (read by lit draws; an input that ends before them decodes them as
//   zero bytes: no lights, default-like materials) u8 lights % 5, per light: u8 kind % 3,
//   3 x F radiance, 3 x F position, 3 x F direction, u8 inverse_square, F cone scale,
//   F cone offset; 3 x F ambient light; u8 frequency % 3; u8 srgb; per draw: u8 model % kNumMaterialModels,
//   u8 flags (kd_is_base, ka_is_kd, double_sided), 3 x F ka, kd, ks, emissive, F shininess,
//   metallic, roughness;
//   then textures (an input that ends before them has none): u8 texture_filter (0xff: each
//   texture's own, else % 4), one texture: u8 width-1 % 64, u8 height-1 % 64, u8 channels
//   (1 + c % 4), u8 format (bit 0: float32 texels as F values, else raw u8; bit 1 sRGB; bit 2
//   top_left; bit 3 build mips), u8 filter % 4, u8 wrap_u % 3, u8 wrap_v % 3, u8 max
//   anisotropy (1 + a % 32), the texels, then per draw u8 slots (bit 0 base colour, 1 emissive,
//   2 normal, 3 metallic-roughness, 4 occlusion, 5 bump; bit 6: alpha mask) and F normal_scale,
//   u8 normal_y_down (then, for the later slots: F occlusion_strength, F bump_scale; for an
//   alpha mask: F alpha_cutoff);
//   then u8 surface outputs (bits 0-3: barycentric, uv, position, ray_depth; bit 4: normals in
//   camera space; bit 5: alpha; bits 6-7: anti-aliasing);
//   then u8 extras (bit 0: cull_double_sided; bit 1: shading normals; bit 2: the texture is also
//   every draw's specular texture; bit 3: double-sided materials never culled; bits 4-5:
//   primitives % 3, bit 6: the dda line algorithm), per primitive: u8 flags (bit 0 points, bit 1
//   per-position colours), u8 positions (1 + p % 8), each 3 x F, lines: u8 segments % 9, each
//   two u8 % positions; colours 3 x F each; F width, M model, i32 instance id, F depth bias.
// F (float) / D (double) values: u8 selector, then for some selectors a payload (see value()).
// I (face index): u8 < 0xf0 => that byte % vertices, else a special value (see index()).
// M (matrix): u8 mode: identity, translation, scale + translation, 16 raw values, mirror.
// P (projection): u8 mode: perspective(fovy, aspect, near, far), ortho, 16 raw values, identity.
#include "framebuffer.hpp"
#include "lines.hpp"
#include "renderer.hpp"
#include "texture.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>

#include <glm/gtc/matrix_transform.hpp>

using namespace sr;

namespace {

class Reader {
 public:
  Reader(const uint8_t* data, std::size_t size) : p_(data), end_(data + size) {}

  template <typename T>
  T raw() {
    uint8_t bytes[sizeof(T)] = {};
    for (std::size_t i = 0; i < sizeof(T) && p_ < end_; ++i) bytes[i] = *p_++;
    T v;
    std::memcpy(&v, bytes, sizeof(T));
    return v;
  }
  uint8_t u8() { return raw<uint8_t>(); }

  // Special values first, so short selectors reach the edge cases.
  double value() {
    const uint8_t sel = u8();
    switch (sel % 16) {
      case 0: return 0.0;
      case 1: return std::numeric_limits<double>::quiet_NaN();
      case 2: return std::numeric_limits<double>::infinity();
      case 3: return -std::numeric_limits<double>::infinity();
      case 4: return 3e38;   // near FLT_MAX
      case 5: return -1e30;
      case 6: return 1e-30;  // tiny
      case 7: return 1.4e-45;  // float denormal
      case 8: return -0.0;
      case 9: return double(raw<float>());  // any float bit pattern
      case 10: return raw<double>();        // any double bit pattern
      case 11: return double(raw<int16_t>()) * 1024.0;  // large but ordinary
      default: return double(raw<int16_t>()) / 256.0;   // ordinary, sub-pixel steps
    }
  }
  float value_f() { return float(value()); }

  int32_t index(int32_t n) {
    const uint8_t b = u8();
    if (b < 0xf0) return n > 0 ? int32_t(b % n) : int32_t(b);
    switch (b) {
      case 0xf0: return -1;
      case 0xf1: return n;
      case 0xf2: return std::numeric_limits<int32_t>::min();
      case 0xf3: return std::numeric_limits<int32_t>::max();
      default: return raw<int32_t>();
    }
  }

  dmat4 matrix() {
    dmat4 m(1.0);
    switch (u8() % 6) {
      case 0: break;
      case 1: for (int r = 0; r < 3; ++r) m[3][r] = value(); break;
      case 2:
        for (int r = 0; r < 3; ++r) m[r][r] = value();
        for (int r = 0; r < 3; ++r) m[3][r] = value();
        break;
      case 3: for (int c = 0; c < 4; ++c) for (int r = 0; r < 4; ++r) m[c][r] = value(); break;
      case 4:  // rotation about a fuzzed axis by a fuzzed angle, then translation
        m = glm::rotate(dmat4(1.0), value(), dvec3(value(), value(), value()));
        for (int r = 0; r < 3; ++r) m[3][r] = value();
        break;
      default: m[0][0] = -1.0; for (int r = 0; r < 3; ++r) m[3][r] = value(); break;  // mirror
    }
    return m;
  }

  dmat4 projection(double near, double far, double aspect) {
    const uint8_t mode = u8() % 4;
    if (mode == 0) return glm::perspective(value(), aspect, near, far);
    if (mode == 1) {
      const double x = value(), y = value();
      return glm::ortho(-x, x, -y, y, near, far);
    }
    dmat4 m(1.0);
    if (mode == 2)
      for (int c = 0; c < 4; ++c) for (int r = 0; r < 4; ++r) m[c][r] = value();
    return m;
  }

 private:
  const uint8_t* p_;
  const uint8_t* end_;
};

// -DFUZZ_TRACE prints what each input decoded to (to check seeds: fuzz_render corpus/*.bin).
template <typename... Args>
void trace([[maybe_unused]] const char* format, [[maybe_unused]] Args... args) {
#ifdef FUZZ_TRACE
  std::fprintf(stderr, format, args...);
#endif
}

[[noreturn]] void fail(const char* what, int i) {
  std::fprintf(stderr, "invariant violated: %s (pixel %d)\n", what, i);
  std::abort();
}

template <typename V>
void fill(Reader& in, std::vector<V>& out, std::size_t n, int comps) {
  const uint8_t mode = in.u8() % 4;
  if (mode == 0) return;
  const std::size_t count = mode == 1 ? n : mode == 2 ? n + 1 : (n > 0 ? n - 1 : 0);
  out.resize(count);
  for (V& v : out)
    for (int k = 0; k < comps; ++k) v[k] = in.value_f();
}

// Checks what the README promises of any successful render; returns the number of hits.
int check_frame(const Framebuffer& fb, const MeshData& mesh, std::size_t num_draws,
                 const uint8_t background[3], bool primitives) {
  const int n = fb.width * fb.height;
  int hits = 0;
  for (int i = 0; i < n; ++i) {
    // Hit: derived from whichever output says it; all that are present must agree.
    int hit = -1;
    auto agree = [&](bool h, const char* what) {
      if (hit >= 0 && bool(hit) != h) fail(what, i);
      hit = h;
    };
    if (fb.get<bool>(kOutMask)) agree(fb.get<bool>(kOutMask)[i], "mask");
    if (fb.get<float>(kOutDepth)) {
      if (!(std::isfinite(fb.get<float>(kOutDepth)[i]) && fb.get<float>(kOutDepth)[i] >= 0.0f)) fail("depth finite and >= 0", i);
      agree(fb.get<float>(kOutDepth)[i] > 0.0f, "mask == (depth > 0)");
    }
    if (fb.get<int32_t>(kOutTriangleId)) {
      if (fb.get<int32_t>(kOutTriangleId)[i] < -1 || fb.get<int32_t>(kOutTriangleId)[i] >= int64_t(mesh.faces.size()))
        fail("triangle_id in [-1, faces)", i);
      // (lines and points: triangle_id -1 on their pixels, and no coverage)
      if (!primitives)
        agree(fb.get<int32_t>(kOutTriangleId)[i] != -1, "triangle_id == -1 exactly where mask is false");
      else if (hit == 0 && fb.get<int32_t>(kOutTriangleId)[i] != -1)
        fail("background triangle_id", i);
    }
    if (fb.get<uint32_t>(kOutCoverage) && hit == 1 && !primitives && fb.get<uint32_t>(kOutCoverage)[i] == 0) fail("visible pixel has coverage 0", i);
    if (fb.get<int32_t>(kOutInstanceId) && hit == 0 && fb.get<int32_t>(kOutInstanceId)[i] != -1) fail("background instance_id", i);
    if (fb.get<float>(kOutNormal)) {
      const float* nrm = fb.get<float>(kOutNormal) + 3 * i;
      for (int k = 0; k < 3; ++k)
        if (!std::isfinite(nrm[k])) fail("normal finite", i);
      if (hit == 0 && (nrm[0] != 0.0f || nrm[1] != 0.0f || nrm[2] != 0.0f))
        fail("background normal is 0", i);
    }
    if (fb.get<uint8_t>(kOutColor) && hit == 0 && std::memcmp(fb.get<uint8_t>(kOutColor) + 3 * i, background, 3) != 0)
      fail("background colour", i);
    if (fb.get<float>(kOutRadiance) && hit == 0) {
      const float* rad = fb.get<float>(kOutRadiance) + 3 * i;
      if (rad[0] != 0.0f || rad[1] != 0.0f || rad[2] != 0.0f) fail("background radiance is 0", i);
    }
    if (const float* b = fb.get<float>(kOutBarycentric)) {
      const float* w = b + 3 * i;
      if (hit == 0 && (w[0] != 0.0f || w[1] != 0.0f || w[2] != 0.0f)) fail("background barycentric is 0", i);
      // The weights are finite and sum to 1 (NaN fails), up to float rounding of their size; a
      // line or point pixel has none (0). They are the exact hit's on the face's plane, so they
      // leave [0, 1] where the snapped triangle covers a centre just outside the true one (by
      // the snap over the triangle's height: on a fuzzed sliver, by any amount).
      const bool none = w[0] == 0.0f && w[1] == 0.0f && w[2] == 0.0f;
      const float size = std::fabs(w[0]) + std::fabs(w[1]) + std::fabs(w[2]);
      if (hit == 1 && !(primitives && none) &&
          !(std::isfinite(size) && std::fabs(w[0] + w[1] + w[2] - 1.0f) < 1e-5f * std::max(1.0f, size)))
        fail("barycentric weights summing to 1", i);
    }
    for (OutputBit bit : {kOutUv, kOutPosition, kOutRayDepth}) {
      const float* v = fb.get<float>(bit);
      if (!v) continue;
      const int c = kOutputLayouts[output_index(bit)].channels;
      for (int k = 0; k < c; ++k)
        if (hit == 0 && v[c * i + k] != 0.0f) fail("background uv / position / ray_depth is 0", i);
    }
    if (const float* r = fb.get<float>(kOutRayDepth))
      if (hit == 1 && r[i] < 0.0f) fail("ray_depth not negative", i);
    if (const float* a = fb.get<float>(kOutAlpha)) {
      if (!(a[i] >= 0.0f && a[i] <= 1.0f)) fail("alpha in [0, 1]", i);
      agree(a[i] > 0.0f, "mask == (alpha > 0)");
    }
    if (hit == 1 && num_draws == 0 && !primitives) fail("a hit without draws", i);
    hits += hit == 1;
  }
  return hits;
}

bool same_frames(const Framebuffer& a, const Framebuffer& b) {
  for (int i = 0; i < kNumOutputs; ++i) {
    if (!(a.outputs & kOutputLayouts[i].bit)) continue;
    const std::size_t bytes = std::size_t(a.width) * a.height * kOutputLayouts[i].bytes_per_pixel();
    if (std::memcmp(a.data(i), b.data(i), bytes) != 0) return false;
  }
  return true;
}

// Renderers are kept between inputs (as a Python user keeps one), so scratch reuse is fuzzed too.
Renderer& renderer(int width, int height, int threads, bool simd = true) {
  static std::unique_ptr<Renderer> cache[4][2];
  std::unique_ptr<Renderer>& r = cache[threads][simd];
  if (!r || r->width() != width || r->height() != height)
    r = std::make_unique<Renderer>(width, height, threads, simd);
  return *r;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  Reader in(data, size);
  const int width = 1 + in.u8(), height = 1 + in.u8();
  const int threads = 1 + in.u8() % 3;
  RenderOptions options;
  options.outputs = in.u8();
  options.cull = Cull(in.u8() % 3);
  options.shading = Shading(in.u8() % kNumShadings);
  const uint8_t flags = in.u8();
  for (int c = 0; c < 3; ++c) options.background[c] = in.value_f();
  options.ambient = in.value_f();

  CameraParams camera;
  camera.orthographic = flags & 1;
  camera.view = in.matrix();
  const double near = in.value(), far = in.value();
  camera.proj = in.projection(near, far, double(width) / height);
  camera.near = near;
  camera.far = far;

  MeshVectors arrays;
  arrays.positions.resize(in.u8());
  for (vec3& p : arrays.positions) p = vec3(in.value_f(), in.value_f(), in.value_f());
  const int32_t n = int32_t(arrays.positions.size());
  arrays.faces.resize(in.u8());
  for (ivec3& f : arrays.faces) f = ivec3(in.index(n), in.index(n), in.index(n));
  fill(in, arrays.normals, n, 3);
  fill(in, arrays.colors, n, 4);
  fill(in, arrays.uvs, n, 2);
  const std::shared_ptr<MeshData> mesh = MeshData::from_vectors(std::move(arrays));

  std::vector<Draw> draws(in.u8() % 4);
  for (Draw& d : draws) {
    d.mesh = mesh;
    d.model = in.matrix();
    d.instance_id = in.raw<int32_t>();
    d.color = vec4(in.value_f(), in.value_f(), in.value_f(), in.value_f());
  }

  const int num_lights = in.u8() % 5;
  for (int k = 0; k < num_lights; ++k) {
    Light light;
    light.kind = LightKind(in.u8() % 3);
    light.radiance = vec3(in.value_f(), in.value_f(), in.value_f());
    light.position = vec3(in.value_f(), in.value_f(), in.value_f());
    light.direction = vec3(in.value_f(), in.value_f(), in.value_f());
    light.inverse_square = in.u8() & 1;
    light.cone_scale = in.value_f();
    light.cone_offset = in.value_f();
    options.lights.push_back(light);
  }
  options.ambient_light = vec3(in.value_f(), in.value_f(), in.value_f());
  options.has_ambient_light = options.ambient_light != vec3(0.0f);
  options.frequency = Frequency(in.u8() % 3);
  options.srgb = in.u8() & 1;
  for (Draw& d : draws) {
    Material& m = d.material;
    m.model = Brdf(in.u8() % kNumMaterialModels);
    const uint8_t f = in.u8();
    m.kd_is_base = !(f & 1);
    m.ka_is_kd = !(f & 2);
    m.double_sided = !(f & 4);
    for (vec3* v : {&m.ka, &m.kd, &m.ks, &m.emissive}) *v = vec3(in.value_f(), in.value_f(), in.value_f());
    m.shininess = in.value_f();
    m.metallic = in.value_f();
    m.roughness = in.value_f();
  }

  options.texture_filter = in.u8();
  if (options.texture_filter != 0xff) options.texture_filter %= 4;
  const int tw = 1 + in.u8() % 64, th = 1 + in.u8() % 64, tc = 1 + in.u8() % 4;
  const uint8_t format = in.u8();
  std::vector<uint8_t> texels8;
  std::vector<float> texels32;
  std::unique_ptr<Texture> texture;
  if (format & 1) {
    texels32.resize(std::size_t(tw) * th * tc);
    for (float& v : texels32) v = in.value_f();
    texture = std::make_unique<Texture>(tw, th, tc, texels32.data());
  } else {
    texels8.resize(std::size_t(tw) * th * tc);
    for (uint8_t& v : texels8) v = in.u8();
    texture = std::make_unique<Texture>(tw, th, tc, texels8.data(), (format & 2) != 0);
  }
  texture->top_left = (format & 4) != 0;
  texture->filter = TextureFilter(in.u8() % 4);
  texture->wrap_u = Wrap(in.u8() % 3);
  texture->wrap_v = Wrap(in.u8() % 3);
  texture->max_anisotropy = 1 + in.u8() % 32;
  if (format & 8) texture->build_mips();
  for (Draw& d : draws) {
    const uint8_t slots = in.u8();
    Material& m = d.material;
    if (slots & 1) m.base_color_texture = texture.get();
    if (slots & 2) {
      m.emissive_texture = texture.get();
      m.emissive_factor = m.emissive;
      m.emissive = vec3(0.0f);
    }
    if (slots & 4) m.normal_texture = texture.get();
    m.normal_scale = in.value_f();
    m.normal_y_down = in.u8() & 1;
    if (slots & 8) m.metallic_roughness_texture = texture.get();
    if (slots & 16) m.occlusion_texture = texture.get();
    if (slots & 32) m.bump_texture = texture.get();
    if (slots & 56) {
      m.occlusion_strength = in.value_f();
      m.bump_scale = in.value_f();
    }
    if (slots & 64) {
      m.alpha_mask = true;
      m.alpha_cutoff = in.value_f();
    }
  }

  const uint8_t surface = in.u8();
  options.outputs |= uint32_t(surface & 15) << 8;  // kOutBarycentric ...
  options.normal_camera = surface & 16;
  if (surface & 32) options.outputs |= kOutAlpha;
  switch (surface >> 6) {  // anti-aliasing: off, msaa 4, ssaa 2, msaa 8
    case 1: options.msaa = 4; break;
    case 2: options.ssaa = 2; break;
    case 3: options.msaa = 8; break;
    default: break;
  }

  const uint8_t extras = in.u8();
  options.cull_double_sided = extras & 1;
  options.shading_normals = extras & 2;
  for (Draw& d : draws) {
    if (extras & 4) d.material.specular_texture = texture.get();
    d.never_culled = (extras & 8) && d.material.double_sided;
  }
  // Lines and points: their arrays live in `prim_data` (the draws view them).
  struct PrimitiveArrays {
    std::vector<vec3> positions, colors;
    std::vector<glm::ivec2> segments;
  };
  std::vector<PrimitiveArrays> prim_data((extras >> 4) % 4 % 3);
  std::vector<PrimitiveDraw> primitives(prim_data.size());
  for (std::size_t k = 0; k < primitives.size(); ++k) {
    PrimitiveArrays& a = prim_data[k];
    PrimitiveDraw& p = primitives[k];
    const uint8_t pf = in.u8();
    p.points = pf & 1;
    a.positions.resize(1 + in.u8() % 8);
    for (vec3& v : a.positions) v = vec3(in.value_f(), in.value_f(), in.value_f());
    const int np = int(a.positions.size());
    if (!p.points) {
      a.segments.resize(in.u8() % 9);
      for (glm::ivec2& s : a.segments) s = glm::ivec2(in.u8() % np, in.u8() % np);
    }
    if (pf & 2) {
      a.colors.resize(a.positions.size());
      for (vec3& c : a.colors) c = vec3(in.value_f(), in.value_f(), in.value_f());
    }
    p.positions = view_of(a.positions);
    p.segments = view_of(a.segments);
    p.colors = view_of(a.colors);
    p.width = in.value_f();
    p.model = in.matrix();
    p.instance_id = in.raw<int32_t>();
    p.depth_bias = in.value_f();
  }
  const LineAlgorithm line_algorithm = extras & 64 ? LineAlgorithm::Dda : LineAlgorithm::Bresenham;

  try {
    mesh->validate();
  } catch (const std::invalid_argument& e) {
    trace("mesh refused: %s\n", e.what());
    return 0;  // rejected before rendering, as the bindings do
  }
  std::unique_ptr<Framebuffer> fb;
  try {
    for (std::size_t k = 0; k < primitives.size(); ++k)
      validate_primitive(primitives[k], "primitive " + std::to_string(k));
    fb = renderer(width, height, threads).render(draws, camera, options, nullptr, primitives,
                                                 line_algorithm);
  } catch (const std::invalid_argument& e) {
    trace("render refused: %s\n", e.what());
    return 0;  // bad camera or options
  }
  uint8_t background[3];
  for (int c = 0; c < 3; ++c)
    background[c] = uint8_t(std::clamp(options.background[c], 0.0f, 1.0f) * 255.0f + 0.5f);
  const int hits = check_frame(*fb, *mesh, draws.size(), background, !primitives.empty());
  trace("rendered %dx%d, %zu vertices, %zu faces, %zu draws, outputs 0x%x: %d hits\n", width,
        height, mesh->positions.size(), mesh->faces.size(), draws.size(),
        unsigned(options.outputs), hits);

  if (flags & 2) {  // bit-identical for any thread count and either kernel set (README: determinism)
    const int other = 1 + threads % 3;
    const bool simd = !(flags & 4);
    auto fb2 = renderer(width, height, other, simd).render(draws, camera, options, nullptr,
                                                           primitives, line_algorithm);
    if (!same_frames(*fb, *fb2)) fail("same frame for 1, 2 and 3 threads, AVX2 and generic kernels", -1);
  }
  return 0;
}
