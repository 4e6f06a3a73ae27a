// Renderer: validation, then the three parallel passes.
#include "renderer.hpp"

#include "clip.hpp"
#include "lit_kernels.hpp"
#include "normals.hpp"
#include "outputs.hpp"
#include "plan.hpp"
#include "shade.hpp"
#include "transform.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <pthread.h>
#include <stdexcept>
#include <string>

namespace sr {

namespace {

// fork() copies only the thread that calls it: a render running on another thread would leave
// its Renderer's mutex locked for good in the child (and its scratch half written). So every
// live Renderer's mutex is registered here, and pthread_atfork's prepare handler takes them all:
// fork() waits until the renders in progress end; the parent and child handlers release them.
// No deadlock: a render holds its mutex without waiting for anything the forking thread may
// hold (from Python it runs with the GIL released, bindings.cpp), and Renderers take the
// registry's lock only to add or remove themselves. Never freed: a Renderer may be destroyed
// during exit, after static destructors have run.
struct ForkGuard {
  std::mutex mutex;
  std::vector<std::mutex*> renderers;
};
ForkGuard& fork_guard() {
  static ForkGuard* const guard = new ForkGuard;
  return *guard;
}
void lock_renderers() {
  ForkGuard& guard = fork_guard();
  guard.mutex.lock();
  for (std::mutex* m : guard.renderers) m->lock();
}
void unlock_renderers() {
  ForkGuard& guard = fork_guard();
  for (std::mutex* m : guard.renderers) m->unlock();
  guard.mutex.unlock();
}
// Registered when the library loads (the guard is created first, not inside fork()).
[[maybe_unused]] const int g_fork_handlers =
    (fork_guard(), pthread_atfork(lock_renderers, unlock_renderers, unlock_renderers));

// Vertices per work item: small enough that a mid-size mesh splits evenly over the threads
// (16384 gave an 81,920-face icosphere three items for two threads).
constexpr std::size_t kVertexBlock = 4096;

// Faces per setup chunk: kTriangleChunk, or fewer for a small draw, so that its setup still
// splits over the threads (a 1,280-face sphere was one chunk, set up on one thread). Chunking
// does not change the output: records keep primitive order across chunks.
constexpr std::size_t kMinChunkFaces = 256, kMinChunks = 2;
std::size_t chunk_faces(std::size_t faces) {
  const std::size_t share = (faces + kMinChunks - 1) / kMinChunks;
  return std::clamp((share + 7) / 8 * 8, kMinChunkFaces, std::size_t(kTriangleChunk));
}

template <typename M>
bool all_finite(const M& m) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) return false;
  return true;
}
bool all_finite(const vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Validation reads a whole mesh when it is uploaded, which from Python happens in the first frame
// that draws it (31 MB for a 1.3M-face mesh): branch-free scans run much faster than loops that
// test and branch per value (benchmarks/RESULTS.md, "Measurements behind the code").
// The scans below are branch-free within a block, so they vectorise; a block that holds a bad
// value is scanned again for the first one, to report it.
constexpr std::size_t kScanBlock = 4096;

// Index of the first of `count` floats that is NaN or infinite, else `count`.
std::size_t first_non_finite(const float* values, std::size_t count) {
  for (std::size_t begin = 0; begin < count; begin += kScanBlock) {
    const std::size_t end = std::min(count, begin + kScanBlock);
    uint32_t bad = 0;
    for (std::size_t i = begin; i < end; ++i) {
      uint32_t bits;
      std::memcpy(&bits, &values[i], sizeof(bits));
      bad |= uint32_t((bits & 0x7f800000u) == 0x7f800000u);  // exponent all ones: inf or NaN
    }
    if (bad)
      for (std::size_t i = begin; i < end; ++i)
        if (!std::isfinite(values[i])) return i;
  }
  return count;
}

// Index of the first of `count` indices outside [0, n), else `count` (n <= INT32_MAX).
std::size_t first_out_of_range(const int32_t* indices, std::size_t count, std::size_t n) {
  for (std::size_t begin = 0; begin < count; begin += kScanBlock) {
    const std::size_t end = std::min(count, begin + kScanBlock);
    uint32_t bad = 0;
    for (std::size_t i = begin; i < end; ++i)
      bad |= uint32_t(uint32_t(indices[i]) >= uint32_t(n));  // a negative index wraps to >= 2^31
    if (bad)
      for (std::size_t i = begin; i < end; ++i)
        if (uint32_t(indices[i]) >= uint32_t(n)) return i;
  }
  return count;
}

}  // namespace

void MeshData::validate() const {
  const std::size_t n = positions.size();
  if (n == 0 || faces.empty()) throw std::invalid_argument("mesh is empty (no vertices or faces)");
  if (n > std::size_t(INT32_MAX)) throw std::invalid_argument("positions: too many vertices");
  if (faces.size() > std::size_t(INT32_MAX)) throw std::invalid_argument("faces: too many faces");
  const std::size_t bad_position = first_non_finite(&positions[0].x, 3 * n);
  if (bad_position < 3 * n)
    throw std::invalid_argument("positions contains NaN or inf at vertex " +
                                std::to_string(bad_position / 3));
  const std::size_t bad_index = first_out_of_range(&faces[0].x, 3 * faces.size(), n);
  if (bad_index < 3 * faces.size()) {
    const std::size_t f = bad_index / 3;
    throw std::invalid_argument("faces: index " + std::to_string(faces[f][int(bad_index % 3)]) +
                                " in face " + std::to_string(f) + " is outside [0, " +
                                std::to_string(n) + ")");
  }
  if (!normals.empty() && normals.size() != n)
    throw std::invalid_argument("normals must have one row per vertex");
  if (!colors.empty() && colors.size() != n)
    throw std::invalid_argument("colors must have one row per vertex");
  if (!uvs.empty() && uvs.size() != n) throw std::invalid_argument("uvs must have one row per vertex");
  auto check_finite = [](const float* values, std::size_t count, const char* name) {
    if (first_non_finite(values, count) < count)
      throw std::invalid_argument(std::string(name) + " contains NaN or inf");
  };
  check_finite(reinterpret_cast<const float*>(normals.data()), 3 * normals.size(), "normals");
  check_finite(reinterpret_cast<const float*>(colors.data()), 4 * colors.size(), "colors");
  check_finite(reinterpret_cast<const float*>(uvs.data()), 2 * uvs.size(), "uvs");
}

void validate_camera(const CameraParams& camera) {
  if (!all_finite(camera.view)) throw std::invalid_argument("camera view matrix is not finite");
  if (!all_finite(camera.proj)) throw std::invalid_argument("camera projection matrix is not finite");
  if (!(std::isfinite(camera.near) && camera.near > 0.0))
    throw std::invalid_argument("near must be finite and > 0");
  if (!(std::isfinite(camera.far) && camera.far > camera.near))
    throw std::invalid_argument("far must be finite and > near");
}

namespace {

// A model lit by the render's lights (the tile's light pass, lighting.hpp).
bool is_lit(Brdf brdf) {
  return brdf == Brdf::Lambert || brdf == Brdf::Phong || brdf == Brdf::BlinnPhong ||
         brdf == Brdf::Pbr;
}

// The render's model for every draw (render(shading=)), or none ("auto": each material's own).
Brdf shading_brdf(Shading shading, Brdf own) {
  switch (shading) {
    case Shading::Unlit: return Brdf::Unlit;
    case Shading::Lambert: return Brdf::Lambert;
    case Shading::Phong: return Brdf::Phong;
    case Shading::BlinnPhong: return Brdf::BlinnPhong;
    case Shading::Pbr: return Brdf::Pbr;
    case Shading::Normal: return Brdf::Normal;
    case Shading::Uv: return Brdf::Uv;
    case Shading::Depth: return Brdf::Depth;
    default: return own;
  }
}

// The plan's choices for one draw: its model in this render and what its triangles read.
// headlight: the render lights plain Lambert draws with the headlight's own formula (Brdf
// Headlight: a scene without lights, every draw plain Lambert, the pixel frequency).
// Without colour there is nothing to shade but normals.
void shade_draw(const RenderPlan& plan, const RenderOptions& options, bool headlight,
                ShadeDraw& d) {
  d.brdf = !plan.color ? Brdf::Unlit
           : headlight ? Brdf::Headlight
                       : shading_brdf(options.shading, d.material.model);
  const Brdf b = d.brdf;
  const bool view = b == Brdf::Uv || b == Brdf::Depth;  // debug views read no material
  const bool textured = plan.color && d.material.textured() && !view && b != Brdf::Headlight;
  // The normal output with the normal or bump map applied (render(normal_kind="shading")).
  const bool normal_map = plan.normal && options.shading_normals && !view &&
                          options.frequency == Frequency::Pixel &&
                          (d.material.normal_texture || d.material.bump_texture);
  d.needs = 0;
  if (plan.normal || (plan.color && b != Brdf::Unlit && !view))
    d.needs |= kNeedsNormal;
  if (is_lit(b) || textured || b == Brdf::Depth) d.needs |= kNeedsPosition;
  if (b == Brdf::Uv || textured) d.needs |= kNeedsUv;
  if (textured) d.needs |= kTexturedUv;
  if (normal_map) d.needs |= kNeedsNormal | kNeedsPosition | kNeedsUv | kTexturedUv;
  if (options.frequency == Frequency::Face && (is_lit(b) || b == Brdf::Normal))
    d.needs |= kNeedsFaceNormal;
  const bool plain = !d.material.textured() || (!plan.color && !normal_map);
  if (b == Brdf::Headlight || view ||
      (plain && (b == Brdf::Unlit || (b == Brdf::Normal && options.frequency == Frequency::Pixel))))
    d.needs |= kInline;
}

// A number as Python's repr writes a float: the shortest text that reads back to it.
std::string number_text(double value) {
  char text[32];
  const auto [end, error] = std::to_chars(text, text + sizeof text, value);
  return error == std::errc() ? std::string(text, end) : std::to_string(value);
}

// A scene without lights is lit by the headlight: a white directional light along the camera's
// viewing axis (the view matrix's third row, negated, for a rigid view) of intensity
// 1 - ambient, and an ambient light of `ambient` unless the scene sets its own.
Light headlight(const CameraParams& camera, double ambient) {
  const dmat4& v = camera.view;  // (glm: v[column][row])
  const double x = -v[0][2], y = -v[1][2], z = -v[2][2];
  const double norm = std::sqrt(x * x + y * y + z * z);
  Light light;
  light.kind = LightKind::Directional;
  light.radiance = vec3(float(1.0 - ambient));
  light.position = vec3(0.0f);
  light.direction = vec3(float(x / norm), float(y / norm), float(z / norm));
  light.inverse_square = false;
  light.cone_scale = 0.0f;
  light.cone_offset = 1.0f;
  return light;
}

}  // namespace

RenderPlan make_plan(const RenderOptions& options, int width, int height) {
  RenderPlan plan;
  plan.outputs = options.outputs;
  plan.color = options.outputs & (kOutColor | kOutRadiance);  // what shading computes
  plan.normal = options.outputs & kOutNormal;
  plan.coverage = options.outputs & kOutCoverage;
  plan.shade = plan.color || plan.normal;
  plan.surface = options.outputs & kSurfaceOutputs;
  // Forward shading kernels do not count coverage (a diagnostic), nor fill by scanline (a
  // cross-check): those renders are deferred, the same bits. The "auto" shading path picks per
  // tile, from overdraw estimated in setup. Anti-aliased renders shade each sample pass's
  // visibility buffer: deferred.
  plan.scanline = options.raster == RasterAlgorithm::Scanline;
  plan.forward_allowed = plan.shade && options.shading_path != ShadingPath::Deferred &&
                         !plan.coverage && !plan.scanline && options.msaa == 1 &&
                         options.ssaa == 1;
  plan.estimate_overdraw = plan.forward_allowed && options.shading_path == ShadingPath::Auto;
  plan.bytes = Framebuffer::bytes_needed(width, height, options.outputs);
  plan.stream = plan.bytes >= kStreamFrameBytes;
  plan.shading = options.shading;
  return plan;
}

Renderer::Renderer(int width, int height, int threads, bool simd)
    : viewport_((width >= 1 && width <= kMaxImageSide && height >= 1 && height <= kMaxImageSide)
                    ? Viewport(width, height)
                    : throw std::invalid_argument(
                          "width and height must be in [1, " + std::to_string(kMaxImageSide) +
                          "], got " + std::to_string(width) + "x" + std::to_string(height))),
      pool_(threads),
      isa_(simd ? best_isa() : Isa::Generic),
      tile_scratch_(pool_.size()),
      shade_scratch_(pool_.size()),
      multisample_scratch_(pool_.size()),
      blend_scratch_(pool_.size()),
      primitive_pixels_(pool_.size()) {
  ForkGuard& guard = fork_guard();
  std::lock_guard<std::mutex> lock(guard.mutex);
  guard.renderers.push_back(&mutex_);
}

Renderer::~Renderer() {
  ForkGuard& guard = fork_guard();
  std::lock_guard<std::mutex> lock(guard.mutex);
  guard.renderers.erase(std::find(guard.renderers.begin(), guard.renderers.end(), &mutex_));
}

std::unique_ptr<Framebuffer> Renderer::render(const std::vector<Draw>& draws,
                                              const CameraParams& camera,
                                              const RenderOptions& options,
                                              std::byte* const* external,
                                              const std::vector<PrimitiveDraw>& primitives,
                                              LineAlgorithm line_algorithm) {
  validate_camera(camera);
  for (std::size_t d = 0; d < primitives.size(); ++d)
    validate_primitive(primitives[d], "primitives[" + std::to_string(d) + "]");
  // Python's RenderOptions checks each of these first, with the same words.
  if (options.outputs == 0 || options.outputs >= (1u << kNumOutputs))
    throw std::invalid_argument("outputs must name at least one output");
  if (!(std::isfinite(options.ambient) && options.ambient >= 0.0f && options.ambient <= 1.0f))
    throw std::invalid_argument("ambient must be in [0, 1], got " + number_text(options.ambient));
  for (int c = 0; c < 3; ++c)
    if (!(options.background[c] >= 0.0f && options.background[c] <= 1.0f))  // NaN fails too
      throw std::invalid_argument("background must be 3 numbers in [0, 1] (RGB), got [" +
                                  number_text(options.background[0]) + ", " +
                                  number_text(options.background[1]) + ", " +
                                  number_text(options.background[2]) + "]");
  for (const Light& light : options.lights) {  // the formulas stay finite for finite inputs
    if (!(all_finite(light.radiance) && all_finite(light.position) && all_finite(light.direction) &&
          std::isfinite(light.cone_scale) && std::isfinite(light.cone_offset)))
      throw std::invalid_argument("lights: a light has a value that is not finite");
  }
  if (options.normal_camera && !(all_finite(options.normal_rotation[0]) &&
                                 all_finite(options.normal_rotation[1]) &&
                                 all_finite(options.normal_rotation[2])))
    throw std::invalid_argument("normal_space: the camera rotation is not finite");
  if (!all_finite(options.ambient_light))
    throw std::invalid_argument("ambient_light is not finite");
  for (std::size_t d = 0; d < draws.size(); ++d) {
    if (!draws[d].mesh) throw std::invalid_argument("draw " + std::to_string(d) + " has no mesh");
    if (!all_finite(draws[d].model))
      throw std::invalid_argument("pose of draw " + std::to_string(d) + " is not finite");
    const vec4 c = draws[d].color;
    if (!(std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b) && std::isfinite(c.a)))
      throw std::invalid_argument("color of draw " + std::to_string(d) + " is not finite");
    const Material& m = draws[d].material;
    if (!(all_finite(m.ka) && all_finite(m.kd) && all_finite(m.ks) && all_finite(m.emissive) &&
          std::isfinite(m.shininess) && m.shininess >= 0.0f && m.metallic >= 0.0f &&
          m.metallic <= 1.0f && m.roughness >= 0.0f && m.roughness <= 1.0f &&
          std::isfinite(m.alpha_cutoff)))
      throw std::invalid_argument("material of draw " + std::to_string(d) + " is out of range");
  }
  if (options.msaa > 1 && options.ssaa > 1)
    throw std::invalid_argument("msaa and ssaa: use one of them, got msaa=" +
                                std::to_string(options.msaa) + ", ssaa=" + std::to_string(options.ssaa));
  // The pixels' samples: msaa_pattern / ssaa_pattern throw for a bad count; a render without
  // anti-aliasing keeps the renderer's one-sample viewport.
  const SamplePattern pattern =
      options.ssaa != 1 ? ssaa_pattern(options.ssaa) : msaa_pattern(options.msaa);
  if (options.ssaa <= 1 && pattern.count > kMaxMsaaSamples)  // (msaa_pattern never makes one)
    throw std::logic_error("msaa pattern with more than 16 samples");
  const Viewport viewport =
      pattern.count > 1 ? Viewport(width(), height(), pattern) : viewport_;
  const bool multisample = viewport.samples.count > 1;
  const RenderPlan plan = make_plan(options, width(), height());
  if (plan.bytes > kMaxFramebufferBytes)
    throw std::invalid_argument("requested outputs need " + std::to_string(plan.bytes) +
                                " bytes, over the limit of " + std::to_string(kMaxFramebufferBytes));

  std::lock_guard<std::mutex> lock(mutex_);
  buffer_pool_->hold_at_least(2 * plan.bytes);
  auto framebuffer = std::make_unique<Framebuffer>(width(), height(), options.outputs, external,
                                                   buffer_pool_.get());
  const ClipPlanes planes(camera, width(), height());

  // Vertices: transform and project, parallel over blocks of every draw.
  std::vector<DrawTransform> transforms;
  struct Block { uint32_t draw; std::size_t begin, end; };
  std::vector<Block> vertex_blocks;
  vertices_.resize(draws.size());
  for (std::size_t d = 0; d < draws.size(); ++d) {
    transforms.push_back(make_draw_transform(draws[d].model, camera));
    const std::size_t n = draws[d].mesh->positions.size();
    vertices_[d].resize(n);
    for (std::size_t b = 0; b < n; b += kVertexBlock)
      vertex_blocks.push_back({uint32_t(d), b, std::min(n, b + kVertexBlock)});
  }
  pool_.parallel_for(vertex_blocks.size(), [&](std::size_t item, int) {
    const Block& blk = vertex_blocks[item];
    project_vertices(*draws[blk.draw].mesh, transforms[blk.draw], blk.begin, blk.end, planes,
                     viewport, camera.orthographic, isa_, vertices_[blk.draw].data());
  });

  // Setup and binning, parallel over fixed-size triangle chunks (primitive order is kept).
  // A masked draw's chunks carry its alpha test; a draw whose one alpha is below its cutoff
  // has none.
  // A blended draw's chunks follow every opaque one (blend.hpp), set up only where some output
  // reads them (colour, radiance, alpha; any, with an alpha threshold).
  std::vector<AlphaTest> alpha_tests(draws.size());
  std::vector<const AlphaTest*> alpha(draws.size(), nullptr);
  std::vector<const AlphaTest*> blend_tests(draws.size(), nullptr);
  std::vector<Block> chunk_ranges, blend_ranges;
  const bool blend_read =
      (options.outputs & (kOutColor | kOutRadiance | kOutAlpha)) != 0 || options.surface_threshold;
  std::vector<uint8_t> casts(draws.size(), 0);  // occluders of shadowed lights (shadow.hpp)
  for (std::size_t d = 0; d < draws.size(); ++d) {
    const AlphaKind kind = alpha_kind(draws[d], options.texture_filter, alpha_tests[d]);
    casts[d] = kind == AlphaKind::Opaque || kind == AlphaKind::Masked;
    if (kind == AlphaKind::Invisible) continue;
    if (kind == AlphaKind::Blended) {
      if (!blend_read) continue;
      blend_tests[d] = &alpha_tests[d];
    }
    if (kind == AlphaKind::Masked) alpha[d] = &alpha_tests[d];
    const std::size_t m = draws[d].mesh->faces.size();
    const std::size_t step = chunk_faces(m);
    for (std::size_t b = 0; b < m; b += step)
      (blend_tests[d] ? blend_ranges : chunk_ranges).push_back({uint32_t(d), b, std::min(m, b + step)});
  }
  const std::size_t num_opaque_chunks = chunk_ranges.size();
  chunk_ranges.insert(chunk_ranges.end(), blend_ranges.begin(), blend_ranges.end());
  // What each draw's shading reads (before setup: whether it writes the exact weights).
  std::vector<ShadeDraw> shade_draws;
  std::vector<Block> normal_blocks;
  world_normals_.resize(draws.size());
  bool defers_light = false;
  // The shading kernel: a plain one where every draw takes its model (shade_models.hpp).
  KernelKind kind = KernelKind::Lit;
  // The headlight's own Lambert: a scene without lights or ambient light, at the pixel frequency,
  // whose draws are all plain Lambert.
  bool headlight_lambert = options.lights.empty() && !options.has_ambient_light &&
                           options.frequency == Frequency::Pixel;
  for (const Draw& d : draws)
    headlight_lambert &= shading_brdf(options.shading, d.material.model) == Brdf::Lambert &&
                         d.material.plain();
  for (std::size_t d = 0; d < draws.size(); ++d) {
    const MeshData& mesh = *draws[d].mesh;
    ShadeDraw sd{&mesh, transforms[d].normal_to_world, draws[d].color, draws[d].material,
                 Brdf::Unlit, 0, draws[d].instance_id, nullptr, draws[d].model,
                 transforms[d].model_view_d};
    shade_draw(plan, options, headlight_lambert, sd);
    sd.exact_shading = (sd.needs & (kNeedsPosition | kNeedsUv)) != 0;
    defers_light |= plan.color && options.frequency == Frequency::Pixel && is_lit(sd.brdf);
    const KernelKind mine = !(sd.needs & kInline)      ? KernelKind::Lit
                            : sd.brdf == Brdf::Headlight ? KernelKind::Headlight
                            : sd.brdf == Brdf::Unlit     ? KernelKind::Unlit
                            : sd.brdf == Brdf::Normal    ? KernelKind::NormalColor
                                                         : KernelKind::Lit;
    kind = options.lit_kernel ? KernelKind::Lit : d == 0 || mine == kind ? mine : KernelKind::Lit;
    const bool smooth = (sd.needs & kNeedsNormal) && !mesh.normals.empty();
    world_normals_[d].resize(smooth ? mesh.normals.size() : 0);
    for (std::size_t b = 0; b < world_normals_[d].size(); b += kVertexBlock)
      normal_blocks.push_back({uint32_t(d), b, std::min(world_normals_[d].size(), b + kVertexBlock)});
    if (smooth) sd.world_normals = world_normals_[d].data();
    shade_draws.push_back(sd);
  }
  if (chunks_.size() < chunk_ranges.size()) chunks_.resize(chunk_ranges.size());
  pool_.parallel_for(chunk_ranges.size(), [&](std::size_t item, int) {
    const Block& blk = chunk_ranges[item];
    const bool blended = blend_tests[blk.draw] != nullptr;
    SetupParams params{draws[blk.draw].mesh.get(), &transforms[blk.draw],
                       vertices_[blk.draw].data(), blk.draw, camera.orthographic,
                       draws[blk.draw].never_culled && !options.cull_double_sided ? Cull::None
                                                                                  : options.cull,
                       &planes, viewport, plan.estimate_overdraw && !blended,
                       plan.shade || plan.surface || alpha[blk.draw] || blended, alpha[blk.draw],
                       isa_};
    // The exact weights where the draw's shading reads them, or the normal output does.
    // (A masked or blended draw's alpha reads them too, whichever outputs are requested.)
    params.exact_weights = (plan.shade && (shade_draws[blk.draw].exact_shading || plan.normal)) ||
                           alpha[blk.draw] || blended;
    setup_chunk(params, blk.begin, blk.end, chunks_[item]);
  });

  // Lines and points: transformed, clipped, projected and binned, parallel over blocks.
  primitives_.build(primitives, camera, viewport, line_algorithm,
                    (options.outputs & (kOutPosition | kOutRayDepth)) != 0, pool_);

  // Tiles: rasterize, then shade, each tile by one thread.
  pool_.parallel_for(normal_blocks.size(), [&](std::size_t item, int) {
    const Block& blk = normal_blocks[item];
    world_normals(*draws[blk.draw].mesh, transforms[blk.draw].normal_to_world, blk.begin, blk.end,
                  isa_, world_normals_[blk.draw].data());
  });
  ShadeParams shade{};
  shade.draws = shade_draws.data();
  shade.lit = &lit_kernels(isa_);
  shade.color = plan.color;
  shade.normal = plan.normal;
  shade.work = uint16_t((plan.color ? kWorkColor : 0) | (plan.normal ? kWorkNormalOut : 0) |
                       (plan.color && defers_light ? kWorkLitCode : 0));
  shade.in.defers_light = defers_light;
  // Headlight: the light sits at the camera and shines along its viewing axis.
  const dvec3 to_camera = glm::normalize(dvec3(glm::inverse(camera.view) * dvec4(0, 0, 1, 0)));
  shade.in.to_light_world = vec3(to_camera);
  shade.in.ambient = float(options.ambient);
  // The depth view: grey = (far - depth) / (far - near), depth = -(view row 2 . p + view[3][2]).
  {
    const double span = camera.far - camera.near;
    const dmat4& v = camera.view;  // (glm: v[column][row])
    shade.in.depth_grey = vec4(float(v[0][2] / span), float(v[1][2] / span),
                               float(v[2][2] / span), float((camera.far + v[3][2]) / span));
  }
  shade.in.frequency = options.frequency;
  shade.in.shading_normals = plan.normal && options.shading_normals &&
                             options.frequency == Frequency::Pixel;
  shade.in.texture_filter = options.texture_filter;
  const bool lights = !options.lights.empty();
  const Light head = lights ? Light{} : headlight(camera, options.ambient);
  shade.in.lit.lights = lights ? options.lights.data() : &head;
  shade.in.lit.num_lights = lights ? int(options.lights.size()) : 1;
  shade.in.lit.ambient_light = options.has_ambient_light ? options.ambient_light
                               : lights                  ? vec3(0.0f)
                                                         : vec3(float(options.ambient));
  // Shadowed lights: the occluders, once per render, only where colour is shaded.
  // (A shadow-mapped light reads its own maps: the hierarchy is built for exact ones only.)
  bool shadowed = false, exact = false;
  for (const Light& light : options.lights) {
    shadowed |= light.shadow != ShadowMethod::None;
    exact |= light.shadow == ShadowMethod::Exact;
  }
  if (shadowed && plan.color) {
    if (exact) {
      shadows_.build(draws, casts);
      shadows_.prepare(options.lights);
    }
    else shadows_.clear();
    shade.in.lit.shadows = &shadows_;
  }
  // The view vector: toward the camera centre (perspective), or along the axis (orthographic).
  const dmat4 camera_to_world = glm::inverse(camera.view);
  shade.in.lit.eye = camera.orthographic ? vec3(to_camera) : vec3(dvec3(camera_to_world[3]));
  shade.in.lit.eye_point = camera.orthographic ? 0.0f : 1.0f;
  for (int c = 0; c < 3; ++c)
    shade.background[c] = uint8_t(std::clamp(options.background[c], 0.0f, 1.0f) * 255.0f + 0.5f);
  shade.srgb = options.srgb;
  shade.orthographic = camera.orthographic;
  shade.stream = plan.stream;
  shade.framebuffer = framebuffer.get();
  shade.normal_rotation = options.normal_camera ? &options.normal_rotation : nullptr;
  shade.camera_centre = dvec3(camera_to_world[3]);
  shade.rays = make_view_rays(camera.proj, viewport.width, viewport.height, camera.orthographic);
  shade.view_to_world = camera_to_world;
  shade.sample_x = viewport.samples.x[0];  // (multisampled tiles: each pixel's representative)
  shade.sample_y = viewport.samples.y[0];
  // The background's linear value, which anti-aliasing mixes into partly covered pixels: the
  // colour output's background byte, decoded as the output is encoded.
  vec3 background_linear(0.0f);
  for (int c = 0; c < 3; ++c) {
    const double v = shade.background[c] / 255.0;
    background_linear[c] = float(!options.srgb ? v
                                 : v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
  }
  const float tie = camera.orthographic ? kTieFactorOrthographic : kTieFactorPerspective;
  const std::size_t num_chunks = num_opaque_chunks;
  const TileKernels kernels = select_tile_kernels(plan, viewport, isa_, kind);
  // Blended layers shade colour only (blend.hpp), and the normal output where the nearest
  // fragment reaching an alpha threshold gives it.
  const bool blend_normals = options.surface_threshold && plan.normal;
  ShadeParams blend_shade = shade;
  if (!blend_normals) {
    blend_shade.normal = false;
    blend_shade.work = uint16_t(shade.work & ~kWorkNormalOut);
    blend_shade.in.shading_normals = false;
  }
  BlendParams blend{(plan.color || blend_normals) && kernels.deferred ? &blend_shade : nullptr,
                    &kernels, &chunks_, num_opaque_chunks, chunk_ranges.size(),
                    blend_tests.data(), background_linear};
  blend.surfaces = options.surface_threshold;
  blend.threshold = options.alpha_threshold;
  blend.normals = blend_normals && blend.shade;
  const bool blending = chunk_ranges.size() > num_opaque_chunks;
  // Every tile is one sequence: rasterize (and shade, forward) -> shade (deferred) -> lines and
  // points over the shaded tile -> write the outputs. Anti-aliased tiles run it per sample pass
  // and resolve (multisample.cpp).
  pool_.parallel_for(viewport.num_tiles(), [&](std::size_t tile, int worker) {
    if (!tile_scratch_[worker]) tile_scratch_[worker].reset(new TileScratch);
    const bool overlay = primitives_.any(int(tile));  // lines or points in this tile
    if (overlay && !primitive_pixels_[worker]) primitive_pixels_[worker].reset(new PrimitivePixels);
    if (multisample) {
      if (!multisample_scratch_[worker]) multisample_scratch_[worker].reset(new MultisampleScratch);
      BlendScratch* blend_scratch = nullptr;
      if (blending) {
        if (!blend_scratch_[worker]) blend_scratch_[worker].reset(new BlendScratch);
        blend_scratch = blend_scratch_[worker].get();
      }
      multisample_tile(shade, kernels, viewport, int(tile), chunks_, num_chunks,
                       options.ssaa > 1, tie, background_linear, *multisample_scratch_[worker],
                       &primitives_, primitive_pixels_[worker].get(), &blend, blend_scratch);
      return;
    }
    if (!shade_scratch_[worker]) shade_scratch_[worker].reset(new ShadeScratch);
    TileScratch& raster = *tile_scratch_[worker];
    ShadeScratch& shaded = *shade_scratch_[worker];
    raster.tie = tie;
    const TileRect rect = tile_rect(viewport, int(tile));

    // Forward shades each fragment as it wins the depth test, deferred each visible pixel once
    // after the walk: the same bits. Lines and points draw over a deferred tile.
    bool forward = plan.forward_allowed && !overlay;
    if (forward && plan.estimate_overdraw) {
      // Deferred walks each triangle twice: forward wins up to about this much overdraw
      // (benchmarks/RESULTS.md, "Stages and scaling": the crossover).
      constexpr float kForwardMaxOverdraw = 1.5f;
      float area = 0.0f;
      for (std::size_t c = 0; c < num_chunks; ++c) area += chunks_[c].tile_area[tile];
      forward = area <= kForwardMaxOverdraw * float((rect.x1 - rect.x0) * (rect.y1 - rect.y0));
    }
    if (forward) {
      shade_forward(kernels, shade, rect, int(tile), chunks_, num_chunks, raster, shaded);
    } else {
      rasterize_tile(kernels.raster, viewport, int(tile), chunks_, num_chunks, plan.coverage,
                     raster);
      if (kernels.deferred) shade_deferred(kernels, shade, rect, raster, shaded);
    }
    PrimitivePixels* pixels = overlay ? primitive_pixels_[worker].get() : nullptr;
    if (overlay) {
      const OverlayTarget target{raster.key, raster.visible,
                                 {shaded.rgb[0], shaded.rgb[1], shaded.rgb[2]},
                                 {shaded.normal[0], shaded.normal[1], shaded.normal[2]},
                                 nullptr, {nullptr, nullptr, nullptr}, tie, pixels};
      draw_primitives_tile(primitives_, rect, int(tile), target);
    }
    BlendScratch* blended = nullptr;
    if (blending) {
      if (!blend_scratch_[worker]) blend_scratch_[worker].reset(new BlendScratch);
      if (blend_tile(blend, rect, int(tile), raster, shaded, *blend_scratch_[worker])) {
        blended = blend_scratch_[worker].get();
        if (blend.surfaces) {
          float* const normal[3] = {shaded.normal[0], shaded.normal[1], shaded.normal[2]};
          take_blend_surfaces(blend, rect, *blended, raster, normal);
        }
      }
    }
    write_tile(shade, rect, raster, shaded, kernels.isa, nullptr, pixels, blended);
  });
  return framebuffer;
}

}  // namespace sr
