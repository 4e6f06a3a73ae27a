// Outputs: resolve (depth from keys, ids from the visibility buffer) and write a tile's rows.
#include "outputs.hpp"

#include "blend.hpp"

#include "interpolate.hpp"
#include "lines.hpp"
#include "multisample.hpp"
#include "surface.hpp"

#include <cmath>
#include <cstring>
#include <stdexcept>
#include <vector>

#if SR_X86
#include <immintrin.h>
#endif

namespace sr {

namespace {

using namespace simd;

// sRGB encoding (IEC 61966-2-1), exactly: the 8-bit code of linear x is round-to-nearest of
// 255 * encode(x), encode(x) = 12.92 x (x <= 0.0031308), 1.055 x^(1/2.4) - 0.055, as evaluated
// in double. Code c starts at the smallest float T_c whose code is c. Floats in [2^-13, 1) are
// split into buckets of 2^15 consecutive bit patterns (256 per octave); a bucket holds at most
// one T_c (the densest codes, near 1, are 1/512 of an octave apart in x; near 2^-13 one code
// spans several buckets), so an entry stores the code at its start and where in it the next
// code starts: code = lo + (low 15 bits >= start). Below 2^-13 (< T_1 = 1.52e-4) the code is 0.
constexpr int kSrgbFirstExp = 127 - 13;  // biased exponent of 2^-13
constexpr int kSrgbBuckets = 13 * 256;
constexpr uint32_t kSrgbNoStart = 0x8000;  // above every 15-bit value

double srgb_encode(double x) {
  return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
}
uint32_t float_bits(float x) { uint32_t b; std::memcpy(&b, &x, 4); return b; }
float bits_float(uint32_t b) { float x; std::memcpy(&x, &b, 4); return x; }
int srgb_code_exact(float x) { return int(std::floor(srgb_encode(double(x)) * 255.0 + 0.5)); }

struct SrgbTable {
  uint32_t entry[kSrgbBuckets];  // code at the bucket's start | (start of the next code) << 8
  SrgbTable() {
    for (int b = 0; b < kSrgbBuckets; ++b) {
      const uint32_t first = (uint32_t(kSrgbFirstExp) << 23) + (uint32_t(b) << 15);
      const int lo = srgb_code_exact(bits_float(first));
      const int hi = srgb_code_exact(bits_float(first + 0x7fff));
      uint32_t start = kSrgbNoStart;
      if (hi == lo + 1) {  // the first pattern of the bucket with the higher code (codes rise)
        uint32_t a = 0, z = 0x7fff;
        while (a < z) {
          const uint32_t m = (a + z) / 2;
          if (srgb_code_exact(bits_float(first + m)) > lo) z = m; else a = m + 1;
        }
        start = a;
      } else if (hi != lo) {
        throw std::logic_error("sRGB table: two codes start in one bucket");
      }
      entry[b] = uint32_t(lo) | start << 8;
    }
  }
};
const SrgbTable& srgb_table() {
  static const SrgbTable table;
  return table;
}
constexpr uint32_t kSrgbLowest = uint32_t(kSrgbFirstExp) << 23;  // 2^-13
constexpr uint32_t kSrgbHighest = 0x3f7fffffu;                   // the float below 1

// The code of one value (NaN and x < 2^-13: 0; x >= 1: 255).
inline uint32_t srgb_code(const uint32_t* table, float x) {
  const float lo = bits_float(kSrgbLowest), hi = bits_float(kSrgbHighest);
  x = x > lo ? x : lo;
  x = x < hi ? x : hi;
  const uint32_t bits = float_bits(x);
  const uint32_t e = table[(bits >> 15) - (kSrgbLowest >> 15)];
  return (e & 0xff) + ((bits & 0x7fff) >= (e >> 8) ? 1u : 0u);
}

// The linear encoding of whole groups of eight; returns how many pixels it packed. Always inline
// and called with pointers only, so that it takes its caller's instruction set (clang refuses
// vector arguments across target boundaries).
SR_INLINE int encode_linear_groups(const float* r, const float* g, const float* b, int n,
                                   uint32_t* out) {
  int x = 0;
  for (; x + kLanes <= n; x += kLanes)
    store(out + x, to_unorm8(load<f8>(r + x)) | (to_unorm8(load<f8>(g + x)) << 8) |
                       (to_unorm8(load<f8>(b + x)) << 16));
  return x;
}

// Packs a row of linear radiance planes to r | g << 8 | b << 16, sRGB-encoded or linear.
void encode_row_generic(const float* r, const float* g, const float* b, const uint32_t*, int n,
                        bool srgb, uint32_t* out) {
  if (srgb) {
    const uint32_t* table = srgb_table().entry;
    for (int x = 0; x < n; ++x)
      out[x] = srgb_code(table, r[x]) | srgb_code(table, g[x]) << 8 | srgb_code(table, b[x]) << 16;
    return;
  }
  const int x = encode_linear_groups(r, g, b, n, out);
  for (int i = x; i < n; ++i) out[i] = to_unorm8(r[i]) | to_unorm8(g[i]) << 8 | to_unorm8(b[i]) << 16;
}
#if SR_X86
SR_TARGET_AVX2 SR_INLINE __m256i srgb_code8(const int* table, __m256 x) {
  x = _mm256_max_ps(x, _mm256_castsi256_ps(_mm256_set1_epi32(int(kSrgbLowest))));  // NaN -> lo
  x = _mm256_min_ps(x, _mm256_castsi256_ps(_mm256_set1_epi32(int(kSrgbHighest))));
  const __m256i bits = _mm256_castps_si256(x);
  const __m256i index = _mm256_sub_epi32(_mm256_srli_epi32(bits, 15), _mm256_set1_epi32(int(kSrgbLowest >> 15)));
  const __m256i e = _mm256_i32gather_epi32(table, index, 4);
  const __m256i low = _mm256_and_si256(bits, _mm256_set1_epi32(0x7fff));
  const __m256i below = _mm256_cmpgt_epi32(_mm256_srli_epi32(e, 8), low);  // start > low: no step
  return _mm256_add_epi32(_mm256_and_si256(e, _mm256_set1_epi32(0xff)),
                          _mm256_add_epi32(_mm256_set1_epi32(1), below));
}
// (Eight pixels of which none is visible are left unwritten: write_rgb writes the background.)
SR_TARGET_AVX2 void encode_row_avx2(const float* r, const float* g, const float* b,
                                    const uint32_t* visible, int n, bool srgb, uint32_t* out) {
  int x = 0;
  if (srgb) {
    const int* table = reinterpret_cast<const int*>(srgb_table().entry);
    const __m256i none = _mm256_set1_epi32(int32_t(kNoTriangle));
    for (; x + kLanes <= n; x += kLanes) {
      const __m256i vis = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(visible + x));
      if (_mm256_movemask_epi8(_mm256_cmpeq_epi32(vis, none)) == -1) continue;
      const __m256i cr = srgb_code8(table, _mm256_loadu_ps(r + x));
      const __m256i cg = srgb_code8(table, _mm256_loadu_ps(g + x));
      const __m256i cb = srgb_code8(table, _mm256_loadu_ps(b + x));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + x),
                          _mm256_or_si256(cr, _mm256_or_si256(_mm256_slli_epi32(cg, 8),
                                                              _mm256_slli_epi32(cb, 16))));
    }
  } else {
    x = encode_linear_groups(r, g, b, n, out);
  }
  encode_row_generic(r + x, g + x, b + x, visible + x, n - x, srgb, out + x);
}
#else  // the x86 kernels' names, for write_tile's choice (never taken elsewhere: no AVX2)
constexpr auto encode_row_avx2 = encode_row_generic;
#endif

// A row of radiance planes interleaved to RGB floats, 0 where nothing is visible.
void write_radiance_row(const float* r, const float* g, const float* b, const uint32_t* visible,
                        int n, float* out) {
  for (int x = 0; x < n; ++x) {
    const bool bg = visible[x] == kNoTriangle;
    out[3 * x] = bg ? 0.0f : r[x];
    out[3 * x + 1] = bg ? 0.0f : g[x];
    out[3 * x + 2] = bg ? 0.0f : b[x];
  }
}

// Depth of the visible pixels of one row, eight at a time.
SR_INLINE void resolve_depth_row(const float* key, const uint32_t* visible, int n,
                                 bool orthographic, float* depth) {
  int x = 0;
  for (; x + kLanes <= n; x += kLanes) {
    const f8 k = load<f8>(key + x);
    const f8 d = orthographic ? -k : 1.0f / k;
    store(depth + x, load<i8>(visible + x) != int32_t(kNoTriangle) ? d : f8{});
  }
  for (; x < n; ++x) depth[x] = visible[x] != kNoTriangle ? depth_from_key(key[x], orthographic) : 0.0f;
}
void resolve_depth_row_generic(const float* key, const uint32_t* visible, int n,
                               bool orthographic, float* depth) {
  resolve_depth_row(key, visible, n, orthographic, depth);
}
#if SR_X86
SR_TARGET_AVX2 void resolve_depth_row_avx2(const float* key, const uint32_t* visible, int n,
                                           bool orthographic, float* depth) {
  resolve_depth_row(key, visible, n, orthographic, depth);
}
// The same values with non-temporal stores, where the row is 16-byte aligned and whole vectors.
SR_TARGET_AVX2 void resolve_depth_row_stream(const float* key, const uint32_t* visible, int n,
                                             bool orthographic, float* depth) {
  if ((reinterpret_cast<uintptr_t>(depth) & 15) != 0 || n % kLanes != 0)
    return resolve_depth_row(key, visible, n, orthographic, depth);
  // Intrinsics rather than f8: clang rejects non-AVX helpers returning 32-byte vectors here.
  const __m256 one = _mm256_set1_ps(1.0f), sign = _mm256_set1_ps(-0.0f);
  const __m256i none = _mm256_set1_epi32(int32_t(kNoTriangle));
  for (int x = 0; x < n; x += kLanes) {
    const __m256 k = _mm256_loadu_ps(key + x);
    const __m256 d = orthographic ? _mm256_xor_ps(k, sign) : _mm256_div_ps(one, k);
    const __m256i vis = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(visible + x));
    const __m256 v = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(vis, none)), d);
    _mm_stream_ps(depth + x, _mm256_castps256_ps128(v));
    _mm_stream_ps(depth + x + 4, _mm256_extractf128_ps(v, 1));
  }
}
#endif

// Unpacks a row of packed colours (r | g << 8 | b << 16) to 3-byte pixels, background where
// nothing is visible.
void write_rgb_generic(const uint32_t* rgb, const uint32_t* visible, int n, uint32_t background,
                       uint8_t* out) {
  for (int x = 0; x < n; ++x) {
    const uint32_t c = visible[x] == kNoTriangle ? background : rgb[x];
    out[3 * x] = uint8_t(c);
    out[3 * x + 1] = uint8_t(c >> 8);
    out[3 * x + 2] = uint8_t(c >> 16);
  }
}
#if SR_X86
// The same, four pixels per byte shuffle (each 16-byte store spills 4 bytes into the next pixel,
// written afterwards; where a spill would leave the row, the last four go as 8 + 4 bytes).
SR_TARGET_AVX2 SR_INLINE __m128i rgb_four(const uint32_t* rgb, const uint32_t* visible,
                                           __m128i background) {
  const __m128i pack = _mm_setr_epi8(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1);
  const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(rgb));
  const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(visible));
  const __m128i none = _mm_cmpeq_epi32(v, _mm_set1_epi32(int32_t(kNoTriangle)));
  return _mm_shuffle_epi8(_mm_blendv_epi8(c, background, none), pack);
}
SR_TARGET_AVX2 void write_rgb_avx2(const uint32_t* rgb, const uint32_t* visible, int n,
                                   uint32_t background, uint8_t* out) {
  const __m128i bg = _mm_set1_epi32(int32_t(background));
  int x = 0;
  for (; x + 6 <= n; x += 4)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + 3 * x), rgb_four(rgb + x, visible + x, bg));
  if (x + 4 <= n) {
    const __m128i last = rgb_four(rgb + x, visible + x, bg);
    _mm_storel_epi64(reinterpret_cast<__m128i*>(out + 3 * x), last);
    const int32_t tail = _mm_extract_epi32(last, 2);
    std::memcpy(out + 3 * x + 8, &tail, 4);
    x += 4;
  }
  write_rgb_generic(rgb + x, visible + x, n - x, background, out + 3 * x);
}

// The same values with non-temporal stores: sixteen pixels as three aligned 16-byte stores,
// where the row is 16-byte aligned and whole groups of sixteen.
SR_TARGET_AVX2 void write_rgb_stream(const uint32_t* rgb, const uint32_t* visible, int n,
                                     uint32_t background, uint8_t* out) {
  if ((reinterpret_cast<uintptr_t>(out) & 15) != 0 || n % 16 != 0)
    return write_rgb_avx2(rgb, visible, n, background, out);
  const __m128i bg = _mm_set1_epi32(int32_t(background));
  for (int x = 0; x < n; x += 16) {
    // Twelve bytes each, the top four zero.
    const __m128i p0 = rgb_four(rgb + x, visible + x, bg);
    const __m128i p1 = rgb_four(rgb + x + 4, visible + x + 4, bg);
    const __m128i p2 = rgb_four(rgb + x + 8, visible + x + 8, bg);
    const __m128i p3 = rgb_four(rgb + x + 12, visible + x + 12, bg);
    __m128i* o = reinterpret_cast<__m128i*>(out + 3 * x);
    _mm_stream_si128(o, _mm_or_si128(p0, _mm_slli_si128(p1, 12)));
    _mm_stream_si128(o + 1, _mm_or_si128(_mm_srli_si128(p1, 4), _mm_slli_si128(p2, 8)));
    _mm_stream_si128(o + 2, _mm_or_si128(_mm_srli_si128(p2, 8), _mm_slli_si128(p3, 4)));
  }
}
#else  // no AVX2 kernels, nor non-temporal stores, on other machines
constexpr auto resolve_depth_row_avx2 = resolve_depth_row_generic;
constexpr auto resolve_depth_row_stream = resolve_depth_row_generic;
constexpr auto write_rgb_avx2 = write_rgb_generic;
constexpr auto write_rgb_stream = write_rgb_generic;
#endif

// The exact surface step's planes of a tile's triangles, computed when a pixel first needs one
// (index = the triangle's entry in the tile's visibility buffer). Per thread, reused.
class ExactPlanes {
 public:
  void reset(std::size_t n) {
    ready_.assign(n, 0);
    if (planes_.size() < n) planes_.resize(n);
  }
  const ExactTriangle& get(const ShadeParams& p, const TileScratch& raster, uint32_t v) {
    if (!ready_[v]) {
      const TriangleSetup& t = *raster.triangles[v].tri;
      const ShadeDraw& d = p.draws[t.draw];
      const ivec3 face = d.mesh->faces[t.prim];
      const vec3* pos = d.mesh->positions.data();
      planes_[v] = exact_triangle(d.model_view, pos[face[0]], pos[face[1]], pos[face[2]]);
      ready_[v] = 1;
    }
    return planes_[v];
  }

 private:
  std::vector<uint8_t> ready_;
  std::vector<ExactTriangle> planes_;
};
// (Not inlined: the caller keeps the address, instead of asking the TLS for it at each use.)
[[gnu::noinline]] ExactPlanes* thread_planes() {
  thread_local ExactPlanes planes;
  return &planes;
}

// Window coordinates of pixel x's sample: its representative's under anti-aliasing.
inline void sample_point(const ShadeParams& p, int px, int y, const int32_t* representative,
                         const SamplePattern* pattern, int x, double& wx, double& wy) {
  const int32_t sx = pattern ? pattern->x[representative[x]] : p.sample_x;
  const int32_t sy = pattern ? pattern->y[representative[x]] : p.sample_y;
  wx = double(px) + double(sx) * (1.0 / kSubpixelOne);
  wy = double(y) + double(sy) * (1.0 / kSubpixelOne);
}

// The visible surface point of each pixel of a row (`n` pixels from column x0 of row y, `visible`
// their entries in the tile's visibility buffer), into each requested surface output (null = not
// requested): the exact step (surface.hpp), the pixel's ray in double on its visible face's
// unsnapped corners. Where the ray misses the face's plane (a face seen edge-on, whose snapped
// triangle still covers the pixel) the perspective-correct weights of the snapped triangle at the
// pixel's sample stand in. Scalar: surface outputs are for datasets.
// With anti-aliasing (`representative` and `pattern` not null), each pixel at its representative
// sample. A line or point pixel (kPrimitivePixel) has no barycentric weights or uv (0), and its
// world position from `primitives` (row `row` of the tile).
void write_surface_row(const ShadeParams& p, const TileScratch& raster, ExactPlanes& planes,
                       const uint32_t* visible, int x0, int y, int n, float* bary_out,
                       float* uv_out, float* position_out, float* ray_depth_out,
                       const int32_t* representative, const SamplePattern* pattern,
                       const PrimitivePixels* primitives, int row) {
  for (int x = 0; x < n; ++x) {
    const uint32_t v = visible[x];
    if (v == kNoTriangle) {
      if (bary_out) for (int c = 0; c < 3; ++c) bary_out[3 * x + c] = 0.0f;
      if (uv_out) uv_out[2 * x] = uv_out[2 * x + 1] = 0.0f;
      if (position_out) for (int c = 0; c < 3; ++c) position_out[3 * x + c] = 0.0f;
      if (ray_depth_out) ray_depth_out[x] = 0.0f;
      continue;
    }
    if (v == kPrimitivePixel) {
      if (bary_out) for (int c = 0; c < 3; ++c) bary_out[3 * x + c] = 0.0f;
      if (uv_out) uv_out[2 * x] = uv_out[2 * x + 1] = 0.0f;
      const dvec3 world(primitives->position[0][row + x], primitives->position[1][row + x],
                        primitives->position[2][row + x]);
      if (position_out) for (int c = 0; c < 3; ++c) position_out[3 * x + c] = float(world[c]);
      if (ray_depth_out)
        ray_depth_out[x] = p.orthographic ? depth_from_key(raster.key[&visible[x] - raster.visible], true)
                                          : float(glm::length(world - p.camera_centre));
      continue;
    }
    const VisibleTriangle& vt = raster.triangles[v];
    const TriangleSetup& t = *vt.tri;
    const ShadeDraw& d = p.draws[t.draw];
    const ivec3 face = d.mesh->faces[t.prim];
    double wx, wy;
    sample_point(p, x0 + x, y, representative, pattern, x, wx, wy);
    ExactHit hit;
    dvec3 w;       // weights of the face's corners
    dvec3 world;   // the point
    double ray_depth;
    if (exact_hit(p.rays, planes.get(p, raster, v), wx, wy, hit)) {
      w = dvec3(hit.bary[0], hit.bary[1], hit.bary[2]);
      if (position_out) world = dvec3(p.view_to_world * dvec4(hit.view, 1.0));
      // (Orthographic: the depth output's value, bit for bit: the key's unless the triangle
      // takes the exact step for its depth.)
      ray_depth = !p.orthographic          ? glm::length(hit.view)
                  : t.flags & kExactDepth ? -hit.view.z
                                          : double(depth_from_key(raster.key[&visible[x] - raster.visible], true));
    } else {  // the snapped triangle's perspective-correct weights at the sample
      const TriangleShading& a = vt.chunk->shading[std::size_t(&t - vt.chunk->records.data())];
      const vec3* clip_weights = a.clip_ref == kNoClip ? nullptr
                                                      : &vt.chunk->clip_bary[3 * std::size_t(a.clip_ref)];
      const int32_t sx = pattern ? pattern->x[representative[x]] : p.sample_x;
      const int32_t sy = pattern ? pattern->y[representative[x]] : p.sample_y;
      const EdgeEquations eq = edge_equations_at(t, x0 + x, y, sx, sy);
      double b[3], sum = 0.0;
      for (int k = 0; k < 3; ++k) sum += b[k] = double(eq.origin[k]) * double(a.persp[k]);
      w = dvec3(0.0);
      for (int k = 0; k < 3; ++k) {
        const double bk = b[k] / sum;
        if (clip_weights) w += bk * dvec3(clip_weights[k]);
        else w[k == 0 ? 0 : a.swapped ? 3 - k : k] += bk;
      }
      dvec3 local(0.0);
      for (int c = 0; c < 3; ++c) local += w[c] * dvec3(d.mesh->positions[face[c]]);
      world = dvec3(d.model_to_world * dvec4(local, 1.0));
      ray_depth = p.orthographic ? double(depth_from_key(raster.key[&visible[x] - raster.visible], true))
                                 : glm::length(world - p.camera_centre);
    }
    if (bary_out) for (int c = 0; c < 3; ++c) bary_out[3 * x + c] = float(w[c]);
    if (uv_out) {
      glm::dvec2 uv(0.0);
      if (!d.mesh->uvs.empty())
        for (int c = 0; c < 3; ++c) uv += w[c] * glm::dvec2(d.mesh->uvs[face[c]]);
      uv_out[2 * x] = float(uv.x);
      uv_out[2 * x + 1] = float(uv.y);
    }
    if (position_out) for (int c = 0; c < 3; ++c) position_out[3 * x + c] = float(world[c]);
    if (ray_depth_out) ray_depth_out[x] = float(ray_depth);
  }
}

// Calls fn(v, x, y, wx, wy) for each pixel (x, y, tile-relative) of the tile whose visible
// triangle v is a sliver (kExactDepth: its float32 key may be off by more than a few units in the
// last place, and it shades with the snapped weights), (wx, wy) its sample's window point (the
// representative's under anti-aliasing). Triangle by triangle over its box, so a tile's other
// pixels cost nothing.
template <typename Fn>
void each_sliver_pixel(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                       const ResolvedSamples* samples, Fn&& fn) {
  const int32_t* representative = samples ? samples->representative : nullptr;
  const SamplePattern* pattern = samples ? samples->pattern : nullptr;
  const uint32_t count = uint32_t(raster.triangles.size());
  for (uint32_t v = 0; v < count; ++v) {
    const TriangleSetup& t = *raster.triangles[v].tri;
    if (!(t.flags & kExactDepth)) continue;
    const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
    const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
    for (int y = y0; y <= y1; ++y) {
      const int row = (y - rect.y0) * kTileSizePx - rect.x0;
      for (int x = x0; x <= x1; ++x) {
        if (raster.visible[row + x] != v) continue;
        double wx, wy;
        sample_point(p, x, y, representative ? representative + row : nullptr, pattern, x, wx, wy);
        fn(v, x - rect.x0, y - rect.y0, wx, wy);
      }
    }
  }
}

// The depth of slivers' pixels, from the pixel's ray on the face's unsnapped plane; the others
// keep the key's depth. `depth` is the tile's first pixel in the output (row stride `stride`).
void exact_depth_tile(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                      ExactPlanes& planes, const ResolvedSamples* samples, float* depth,
                      std::size_t stride) {
  each_sliver_pixel(p, rect, raster, samples, [&](uint32_t v, int x, int y, double wx, double wy) {
    double d;
    if (exact_depth(p.rays, planes.get(p, raster, v), wx, wy, d))
      depth[std::size_t(y) * stride + std::size_t(x)] = float(d);
  });
}

// The normal output of slivers' pixels (their exact weights are the snapped ones: pipeline.hpp,
// ExactWeights): the draw's vertex normals interpolated with the exact step's weights, as
// prepare() fetches them (a zero normal: the face's; turned to the side the camera sees), then as
// write_tile writes them (camera space: rotated). Flat normals are one per face, exact already.
// `normal` is the tile's first pixel in the output (row stride `stride` pixels).
void exact_normal_tile(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                       ExactPlanes& planes, const ResolvedSamples* samples, float* normal,
                       std::size_t stride) {
  each_sliver_pixel(p, rect, raster, samples, [&](uint32_t v, int x, int y, double wx, double wy) {
    const VisibleTriangle& vt = raster.triangles[v];
    const TriangleSetup& t = *vt.tri;
    const ShadeDraw& d = p.draws[t.draw];
    if (!d.world_normals) return;
    ExactHit hit;
    if (!exact_hit(p.rays, planes.get(p, raster, v), wx, wy, hit)) return;
    const ivec3 face = d.mesh->faces[t.prim];
    dvec3 n(0.0);
    for (int c = 0; c < 3; ++c) {
      dvec3 corner(d.world_normals[face[c]]);
      if (corner == dvec3(0.0)) corner = dvec3(interp::flat_normal(d, face.x, face.y, face.z));
      n += hit.bary[c] * corner;
    }
    if (vt.chunk->shading[std::size_t(&t - vt.chunk->records.data())].back_facing) n = -n;
    if (p.normal_rotation) n = dmat3(*p.normal_rotation) * n;
    const double len2 = glm::dot(n, n);
    if (!(len2 > 0.0) || !std::isfinite(len2)) return;
    n /= std::sqrt(len2);
    float* out = normal + 3 * (std::size_t(y) * stride + std::size_t(x));
    for (int c = 0; c < 3; ++c) out[c] = float(n[c]);
  });
}

}  // namespace

void write_tile(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                const ShadeScratch& shaded, Isa isa, const ResolvedSamples* samples,
                const PrimitivePixels* primitives, const BlendScratch* blend) {
  const Framebuffer& fb = *p.framebuffer;
  const std::size_t width = std::size_t(fb.width);
  const int n = rect.x1 - rect.x0;
  const bool stream = p.stream && isa == Isa::Avx2;
  const auto resolve_depth = stream                ? resolve_depth_row_stream
                             : isa == Isa::Avx2    ? resolve_depth_row_avx2
                                                   : resolve_depth_row_generic;
  const auto write_rgb = stream ? write_rgb_stream
                         : isa == Isa::Avx2 ? write_rgb_avx2 : write_rgb_generic;
  // One writer per output (kOutputLayouts), each row by row; null = not requested.
  uint32_t* const coverage = fb.get<uint32_t>(kOutCoverage);
  float* const depth = fb.get<float>(kOutDepth);
  bool* const mask = fb.get<bool>(kOutMask);
  int32_t* const triangle_id = fb.get<int32_t>(kOutTriangleId);
  int32_t* const instance_id = fb.get<int32_t>(kOutInstanceId);
  float* const normal = fb.get<float>(kOutNormal);
  uint8_t* const color = fb.get<uint8_t>(kOutColor);
  float* const radiance = fb.get<float>(kOutRadiance);
  float* const barycentric = fb.get<float>(kOutBarycentric);
  float* const uv = fb.get<float>(kOutUv);
  float* const position = fb.get<float>(kOutPosition);
  float* const ray_depth = fb.get<float>(kOutRayDepth);
  float* const alpha = fb.get<float>(kOutAlpha);
  const bool surface = barycentric || uv || position || ray_depth;
  // The exact step's depth where some triangle of the tile asks for it (kExactDepth).
  const bool exact_depths = depth && (raster.flags & kExactDepth);
  // (Of slivers; not normal_kind="shading": the normal shading read, with its weights.)
  const bool exact_normals = normal && (raster.flags & kExactDepth) && !p.in.shading_normals;
  ExactPlanes& planes = *thread_planes();
  if (surface || exact_depths || exact_normals) planes.reset(raster.triangles.size());
  const bool stream_depth = stream && !exact_depths;  // (not mixed with ordinary stores)
  const auto encode_row = isa == Isa::Avx2 ? encode_row_avx2 : encode_row_generic;
  uint32_t packed[kTileSizePx] = {};  // (encode_row skips groups with nothing visible)
  for (int y = rect.y0; y < rect.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx;
    const std::size_t o = std::size_t(y) * width + std::size_t(rect.x0);
    const uint32_t* visible = raster.visible + row;
    if (coverage)
      std::memcpy(coverage + o, (samples ? samples->coverage : raster.coverage) + row,
                  sizeof(uint32_t) * n);
    if (alpha) {
      if (samples) std::memcpy(alpha + o, samples->alpha + row, sizeof(float) * n);
      else if (blend) std::memcpy(alpha + o, blend->alpha + row, sizeof(float) * n);
      else for (int x = 0; x < n; ++x) alpha[o + x] = visible[x] != kNoTriangle ? 1.0f : 0.0f;
    }
    if (depth)
      (stream_depth || !stream ? resolve_depth : resolve_depth_row_avx2)(raster.key + row, visible, n,
                                                                         p.orthographic, depth + o);
    if (mask)
      for (int x = 0; x < n; ++x) mask[o + x] = visible[x] != kNoTriangle;
    if (triangle_id && !primitives)
      for (int x = 0; x < n; ++x)
        triangle_id[o + x] = visible[x] == kNoTriangle ? -1 : int32_t(raster.triangles[visible[x]].tri->prim);
    if (instance_id && !primitives)
      for (int x = 0; x < n; ++x)
        instance_id[o + x] = visible[x] == kNoTriangle ? -1 : p.draws[raster.triangles[visible[x]].tri->draw].instance_id;
    if (primitives) {  // lines and points: triangle_id -1, their own instance ids
      for (int x = 0; x < n; ++x) {
        const uint32_t v = visible[x];
        const bool tri = v != kNoTriangle && v != kPrimitivePixel;
        if (triangle_id) triangle_id[o + x] = tri ? int32_t(raster.triangles[v].tri->prim) : -1;
        if (instance_id)
          instance_id[o + x] = tri ? p.draws[raster.triangles[v].tri->draw].instance_id
                               : v == kPrimitivePixel ? primitives->instance[row + x] : -1;
      }
    }
    if (normal) {
      float* const out = normal + 3 * o;
      for (int x = 0; x < n; ++x) {
        const bool bg = visible[x] == kNoTriangle;
        for (int c = 0; c < 3; ++c) out[3 * x + c] = bg ? 0.0f : shaded.normal[c][row + x];
      }
      if (p.normal_rotation) {  // camera space: the view's rotation, renormalised
        const mat3& r = *p.normal_rotation;
        for (int x = 0; x < n; ++x) {
          if (visible[x] == kNoTriangle) continue;
          const vec3 m = r * vec3(out[3 * x], out[3 * x + 1], out[3 * x + 2]);
          const float len2 = glm::dot(m, m);
          const vec3 u = len2 > 0.0f ? m * (1.0f / std::sqrt(len2)) : vec3(0.0f);
          for (int c = 0; c < 3; ++c) out[3 * x + c] = u[c];
        }
      }
    }
    if (surface)
      write_surface_row(p, raster, planes, visible, rect.x0, y, n, barycentric ? barycentric + 3 * o : nullptr,
                        uv ? uv + 2 * o : nullptr, position ? position + 3 * o : nullptr,
                        ray_depth ? ray_depth + o : nullptr,
                        samples ? samples->representative + row : nullptr,
                        samples ? samples->pattern : nullptr, primitives, row);
    const float* rgb[3] = {shaded.rgb[0] + row, shaded.rgb[1] + row, shaded.rgb[2] + row};
    if (color) {
      const uint32_t background = p.background[0] | p.background[1] << 8 | p.background[2] << 16;
      if (blend) {  // composited over the opaque surface or the background (blend.hpp)
        encode_row(blend->color[0] + row, blend->color[1] + row, blend->color[2] + row,
                   blend->seen + row, n, p.srgb, packed);
        write_rgb(packed, blend->seen + row, n, background, color + 3 * o);
      } else {
        encode_row(rgb[0], rgb[1], rgb[2], visible, n, p.srgb, packed);
        write_rgb(packed, visible, n, background, color + 3 * o);
      }
    }
    if (radiance) {
      if (blend)
        write_radiance_row(blend->radiance[0] + row, blend->radiance[1] + row,
                           blend->radiance[2] + row, blend->seen + row, n, radiance + 3 * o);
      else if (samples)  // premultiplied: without the background the colour output mixes in
        write_radiance_row(samples->radiance[0] + row, samples->radiance[1] + row,
                           samples->radiance[2] + row, visible, n, radiance + 3 * o);
      else
        write_radiance_row(rgb[0], rgb[1], rgb[2], visible, n, radiance + 3 * o);
    }
  }
  if (exact_depths)
    exact_depth_tile(p, rect, raster, planes, samples,
                     depth + std::size_t(rect.y0) * width + std::size_t(rect.x0), width);
  if (exact_normals)
    exact_normal_tile(p, rect, raster, planes, samples,
                      normal + 3 * (std::size_t(rect.y0) * width + std::size_t(rect.x0)), width);
#if SR_X86
  if (stream) _mm_sfence();  // order the non-temporal stores before the tile is done
#endif
}

}  // namespace sr
