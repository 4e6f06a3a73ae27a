// Records passed between pipeline stages, the option enums and the numeric limits they rely on.
#pragma once

#include "materials.hpp"
#include "math.hpp"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace sr {

// Window coordinates are snapped to 1/256 px "for sub-pixel positioning" (as Direct3D 11 and
// llvmpipe do): x_fixed = round(x_window * 2^SUBPIXEL_BITS).
constexpr int kSubpixelBits = 8;
constexpr int32_t kSubpixelOne = 1 << kSubpixelBits;
constexpr int32_t kSubpixelHalf = kSubpixelOne / 2;  // pixel centres sit at j * 256 + 128

// Guard band: vertices within +-2^15 px of the origin are rasterized as they are; triangles
// reaching beyond it are clipped. Fixed-point coordinates then fit in 24 bits (incl. sign), an
// edge-function coefficient in 25 bits and an edge-function value, a sum of two 25x25-bit
// products, in 51 bits: exact in int64.
constexpr double kGuardBandPx = 32768.0 - 1024.0;

// Largest image side; keeps every pixel index and fixed-point sample position in range.
constexpr int kMaxImageSide = 16384;
// Requested outputs needing more than this are refused before anything is allocated.
constexpr std::size_t kMaxFramebufferBytes = std::size_t(4) << 30;


// Triangles are set up and binned in chunks of at most this many (a small draw's are smaller:
// renderer.cpp, chunk_faces): a chunk is the unit of geometry work given to a thread, and the
// draw's face count, not the thread count, decides how records are grouped.
constexpr int kTriangleChunk = 8192;

enum class Cull : uint8_t { None, Back, Front };
// render(shading=): each draw's own material model ("auto"), or one model for every draw: the
// reflectance models and the debug views (names: bindings.cpp). The plan turns it into a Brdf
// per draw (renderer.cpp).
enum class Shading : uint8_t { Auto, Unlit, Lambert, Phong, BlinnPhong, Pbr, Normal, Uv, Depth };
constexpr int kNumShadings = int(Shading::Depth) + 1;
// When fragments are shaded: as they win the depth test (forward), or once per visible pixel
// after the tile is rasterized (deferred). The same bits either way; Auto picks per tile by
// its expected overdraw.
enum class ShadingPath : uint8_t { Auto, Forward, Deferred };
// How triangles are filled: edge functions evaluated at every pixel of the box (the default), or
// scanline spans found by edge walking (scanline.hpp). The same samples either way.
enum class RasterAlgorithm : uint8_t { Edge, Scanline };

// Output buffers, as bits of RenderOptions::outputs; each is a row of kOutputLayouts
// (framebuffer.cpp), which says everything else about it.
enum OutputBit : uint32_t {
  kOutColor = 1u << 0,
  kOutDepth = 1u << 1,
  kOutMask = 1u << 2,
  kOutNormal = 1u << 3,
  kOutTriangleId = 1u << 4,
  kOutInstanceId = 1u << 5,
  kOutCoverage = 1u << 6,
  kOutRadiance = 1u << 7,
  kOutBarycentric = 1u << 8,
  kOutUv = 1u << 9,
  kOutPosition = 1u << 10,
  kOutRayDepth = 1u << 11,
  kOutAlpha = 1u << 12,
};
constexpr int kNumOutputs = 13;
// The outputs read from the visible surface point (outputs.cpp, write_surface_row): they need
// each triangle's TriangleShading, as shading does.
constexpr uint32_t kSurfaceOutputs = kOutBarycentric | kOutUv | kOutPosition | kOutRayDepth;

// Read-only view of `size` contiguous T's that something else owns (C++20's std::span<const T>,
// as much of it as the stages use).
template <typename T>
class ConstSpan {
 public:
  ConstSpan() = default;
  ConstSpan(const T* data, std::size_t size) : data_(data), size_(size) {}
  const T* data() const { return data_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + size_; }

 private:
  const T* data_ = nullptr;
  std::size_t size_ = 0;
};

// Mesh arrays held in std::vectors: how C++ callers (benchmarks, the fuzzer) build geometry.
struct MeshVectors {
  std::vector<vec3> positions;
  std::vector<ivec3> faces;
  std::vector<vec3> normals;
  std::vector<vec4> colors;
  std::vector<vec2> uvs;
};

// Geometry uploaded once and checked by validate() (throws std::invalid_argument) before it is
// drawn. The fields view memory kept alive by `owner`, which nobody may write to afterwards:
// validation (indices in range) must stay true. From Python the views are NumPy arrays' memory
// (no copy), in C++ the vectors of a MeshVectors.
struct MeshData {
  ConstSpan<vec3> positions;  // model space
  ConstSpan<ivec3> faces;     // counter-clockwise = front, indices in [0, positions.size())
  ConstSpan<vec3> normals;    // model space, per vertex; empty => flat face normals
  ConstSpan<vec4> colors;     // linear RGBA in [0, 1], per vertex; empty => material colour
  ConstSpan<vec2> uvs;        // per vertex; kept for the texture stage
  std::shared_ptr<const void> owner;  // keeps the viewed memory alive

  // A mesh viewing `arrays`, which it takes over; not validated yet.
  static std::shared_ptr<MeshData> from_vectors(MeshVectors arrays);
  void validate() const;
};

template <typename T>
ConstSpan<T> view_of(const std::vector<T>& v) { return {v.data(), v.size()}; }

inline std::shared_ptr<MeshData> MeshData::from_vectors(MeshVectors arrays) {
  auto owned = std::make_shared<const MeshVectors>(std::move(arrays));
  auto mesh = std::make_shared<MeshData>();
  mesh->positions = view_of(owned->positions);
  mesh->faces = view_of(owned->faces);
  mesh->normals = view_of(owned->normals);
  mesh->colors = view_of(owned->colors);
  mesh->uvs = view_of(owned->uvs);
  mesh->owner = std::move(owned);
  return mesh;
}

// One mesh instance in a draw call.
struct Draw {
  std::shared_ptr<const MeshData> mesh;
  dmat4 model{1.0};      // model -> world
  int32_t instance_id = 0;
  vec4 color{0.8f, 0.8f, 0.8f, 1.0f};  // material colour, linear RGBA
  Material material;     // how it is shaded (materials.hpp): the default one without a material
  // A double-sided material's draw (glTF doubleSided): never culled unless
  // RenderOptions::cull_double_sided. The default material (no material given) is lit two-sided
  // but culled like any other.
  bool never_culled = false;
};

struct CameraParams {
  dmat4 view{1.0};  // world -> view (OpenGL: x right, y up, looking down -z)
  dmat4 proj{1.0};  // view -> clip
  bool orthographic = false;
  double near = 0.05;  // > 0, scene units along the view axis
  double far = 100.0;  // > near
};

struct RenderOptions {
  uint32_t outputs = kOutColor | kOutDepth;
  Cull cull = Cull::Back;
  bool cull_double_sided = false;  // cull also the draws of double-sided materials (never_culled)
  // The normal output with normal and bump maps applied (at the pixel frequency; not under the
  // uv and depth views), else the interpolated vertex normal.
  bool shading_normals = false;
  Shading shading = Shading::Auto;
  ShadingPath shading_path = ShadingPath::Auto;
  RasterAlgorithm raster = RasterAlgorithm::Edge;
  vec3 background{0.0f};  // colour of uncovered pixels, [0, 1], linear
  // The scene's world-space lights; without any, the headlight: a white directional light along
  // the viewing axis of intensity 1 - ambient, and an ambient light of `ambient` (renderer.cpp).
  double ambient = 0.25;
  std::vector<Light> lights;
  bool has_ambient_light = false;  // the scene sets its ambient light (else 0, or the headlight's)
  vec3 ambient_light{0.0f};
  Frequency frequency = Frequency::Pixel;
  bool srgb = true;  // the colour output is sRGB-encoded (IEC 61966-2-1), else linear
  bool lit_kernel = false;  // every draw through the lit kernel (tests, benchmarks: the same bits)
  uint8_t texture_filter = 0xff;  // a TextureFilter for every texture, or 0xff: each its own
  bool normal_camera = false;  // the normal output in camera space: normal_rotation applied
  mat3 normal_rotation{1.0f};  // world -> camera axes (the caller's camera convention)
  // Anti-aliasing (multisample.hpp): msaa samples per pixel (1, 2, 4, 8, 16; shaded once per
  // pixel per triangle) or an ssaa x ssaa grid (each sample shaded); not both above 1.
  int msaa = 1;
  int ssaa = 1;
  // Blended draws (blend.hpp): depth, ids, mask, normal and the surface outputs from the nearest
  // blended fragment whose alpha reaches `alpha_threshold`, in front of the opaque surface
  // (Blender's pass alpha threshold); off: the nearest opaque surface's.
  bool surface_threshold = false;
  float alpha_threshold = 1.0f;  // [0, 1]
};

// Per-vertex result of the transform stage (one draw).
struct ClipVertex {
  vec4 p_clip;       // clip space
  float depth_view;  // -z_view: distance along the viewing axis, scene units
};

// Clip-space vertex carried through clipping with its barycentric weights in the source triangle.
// The float position is what the rest of the pipeline reads (a corner of the face keeps exactly
// the vertex pass's bits, so clipped and unclipped neighbours share their snapped vertices); the
// double one is where clipping computes the points it creates, from the corners transformed in
// double.
struct ClipPoint {
  vec4 p_clip;
  float depth_view;
  vec3 bary_source;  // weights of the original triangle's corners (linear in clip space)
  dvec4 p_clip_d;
  double depth_view_d;
};

// A triangle ready for rasterization: everything per-triangle that the tile pass reads, in one
// 64-byte record (records are cache-line aligned: SetupChunk). Vertices are ordered so that the
// area is positive in y-down window coordinates (a back face in OpenGL's terms keeps its order, a
// front face has two vertices swapped); edge k runs from vertex k+1 to vertex k+2 and its
// function is positive inside.
struct TriangleSetup {
  int32_t x[3], y[3];  // snapped window coordinates, fixed point (kSubpixelBits)
  int32_t x0, y0, x1, y1;  // inclusive pixel range whose centres lie in the bounding box
  float key_over_area[3];  // depth key at each vertex / area2 (see depth key below)
  uint8_t bias[3];     // 0 for top/left edges, 1 otherwise: covered iff E_k - bias_k >= 0
  uint8_t flags;           // kExactDepth
  uint32_t prim;           // face index within the mesh
  uint32_t draw;           // index of the draw
};
// TriangleSetup::flags. kExactDepth: the depth output takes the exact step (surface.hpp) at this
// triangle's pixels, because its float32 key may be off by more than a few units in the last place
// (setup.cpp: slivers, whose keys are not fitted to the true plane).
constexpr uint8_t kExactDepth = 1;
// What shading needs of the same triangle to find its attributes without going back to the
// mesh's faces; a parallel array, written only when colour or normals are requested, or for an
// alpha-masked draw (alpha_mask.hpp) (a depth-only render writes and reads two thirds of the bytes).
struct TriangleShading {
  float persp[3];      // (1 / w_k) / (max_j (1 / w_j) * area2), area2 = twice the area in
                       // fixed-point units^2: E_k * persp[k] is proportional to the perspective-
                       // correct weight of vertex k, the largest about 1 (no float underflow)
  int32_t vertex[3];       // unclipped: the mesh vertex of each vertex (the face's, reordered)
  uint32_t clip_ref;       // kNoClip, or index of 3 ClipPoint::bary_source in the clip table
  uint8_t swapped;         // 1 if vertices 1 and 2 are the face's corners 2 and 1
  uint8_t back_facing;     // 1 if the triangle faces away from the camera (culling off)
};
static_assert(sizeof(TriangleSetup) == 64 && sizeof(TriangleShading) == 32,
              "binning moves these records: keep them compact, a whole cache line or half");
constexpr uint32_t kNoClip = 0xffffffffu;
// The exact weights of a record (interpolate.hpp: what shading and the normal output interpolate
// with): b_j = sum_k q[j][k] E_k, with E_k the snapped triangle's exact edge values at a sample,
// is proportional to vertex j's perspective-correct weight in the *unsnapped* triangle at that
// sample. E_k / area2 are the snapped triangle's barycentrics, a basis of the affine functions
// of window position, so the unsnapped edge function E'_j is sum_k E'_j(v_k) / area2 E_k, and
// E'_j(v_k) / area2' = [j == k] + mu_k[j] (SnapShift, vertex.hpp: how the snap moved v_k, in the
// unsnapped triangle's barycentrics): q[j][k] = persp_j ([j == k] + mu_k[j]). A sliver
// (kExactDepth) keeps its snapped weights: q = diag(persp). Written by setup beside the records
// where some output reads them (SetupParams::exact_weights).
struct ExactWeights {
  float q[3][3];
};
// Edge k of a TriangleSetup runs from vertex kEdgeStart[k] to vertex kEdgeEnd[k].
constexpr int kEdgeStart[3] = {1, 2, 0};
constexpr int kEdgeEnd[3] = {2, 0, 1};

// Depth key stored in the z-buffer: larger is closer, affine in window space.
//   perspective: key = 1 / w_clip = 1 / depth_view   (the "1/w buffer": float32 keeps a relative
//                precision of 2^-24 at any distance, so near/far ratios of 1e9 are harmless)
//   orthographic: key = -depth_view                   (w = 1, depth itself is affine)
// The z-buffer is cleared to -infinity. (Setup computes keys; the write pass turns them back.)
inline float depth_from_key(float key, bool orthographic) {
  return orthographic ? -key : 1.0f / key;
}

}  // namespace sr
