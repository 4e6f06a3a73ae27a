// Shading kernels: the deferred walk and the forward hook over a tile, templated only on which
// outputs are written (colour, normals). A draw's model is a per-triangle branch
// (shade_models.hpp) and lighting and textures are out of line (lit_kernels.hpp), so each kernel is
// compiled once per instruction set, in the kernel files (shade_kernels_*.cpp): one path of one
// instruction set each, so that a parallel build compiles them side by side.
#pragma once

#include "dispatch.hpp"
#include "interpolate.hpp"
#include "lit_kernels.hpp"
#include "shade.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace sr {
namespace shading {

using namespace simd;
using interp::LargeEdges;
using interp::Lanes3;
using interp::prepare;
using interp::weighted;

// n / |n| per lane, zero where n is zero.
SR_INLINE void normalize(f8& nx, f8& ny, f8& nz) {
  const f8 len2 = nx * nx + ny * ny + nz * nz;
  const f8 r = 1.0f / simd::sqrt(len2);
  const i8 nonzero = len2 > 0.0f;
  nx = nonzero ? nx * r : f8{};
  ny = nonzero ? ny * r : f8{};
  nz = nonzero ? nz * r : f8{};
}

// The lanes `mine` of v into the scratch buffer at p, the others kept.
template <bool kPairs, typename T, typename V>
SR_INLINE void merge(T* p, V v, i8 mine) {
  raster::store_lanes<kPairs>(p, mine ? v : raster::load_lanes<kPairs, V>(p));
}

// What one Prepared keeps across the triangles it is made for in turn (a tile's): decisions and
// constants that the next triangle of the same draw may share (shade_models.hpp). Apart from
// Prepared, which stays trivial to construct (its fields are written where they are read).
struct PrepareCaches {
  LitClassCache classes;
  LitConstantsCache constants;
};

// A visible triangle prepared for its pixels: what prepare() fetched and classify() decided, its
// per-pixel constants, and what each group of its pixels does (Work bits, once per triangle): the
// render's shaded outputs are a run-time choice folded in here, not a kernel axis
// (benchmarks/RESULTS.md, "What each kernel axis is worth").
template <KernelKind K>
struct Prepared {
  static constexpr KernelKind kKind = K;
  ShadeTriangle s;
  ShadeConstants c;
  uint16_t work;  // ShadeWork bits
  SR_INLINE void make(const ShadeParams& p, const VisibleTriangle& vt, PrepareCaches& caches) {
    const Brdf brdf = prepare<K>(p, vt, s, caches.classes);
    // The render's bits (p.work: kWorkColor, kWorkNormalOut, kWorkLitCode), then the triangle's.
    const bool varying = p.color && s.color_kind != ShadeTriangle::kConstantColor;
    const bool shading_normal = K == KernelKind::Lit && p.normal && s.normal_out_map;
    const bool varying_normal = p.normal && (!s.one_normal || shading_normal);
    uint16_t w = uint16_t(p.work | (varying && s.color_kind == ShadeTriangle::kVaryingColor ? kWorkVaryingColor : 0) |
                          (varying_normal ? kWorkVaryingNormal : 0) |
                          (shading_normal ? kWorkShadingNormal : 0) |
                          (p.normal && s.one_normal && !shading_normal ? kWorkUnitNormal : 0));
    // The exact weights: for everything (the draw reads positions or uvs: prepare), or else for
    // an interpolated normal output alone (slivers keep the snapped weights).
    if (K == KernelKind::Lit && s.exact)
      w |= kWorkExactWeights;
    else if (varying_normal && !p.in.shading_normals && s.q)  // (normal_kind="shading": shading's)
      w |= kWorkExactNormal;
    work = w;
    make_constants<K>(p.in, p.lit, brdf, varying || varying_normal, s, c, caches.constants);
  }
};

// The exact weights (ShadeTriangle::q) from the exact edge values e0..e2, unnormalised.
SR_INLINE void exact_weights(const float (*q)[3], f8 e0, f8 e1, f8 e2, f8& b0, f8& b1, f8& b2) {
  b0 = e0 * q[0][0] + e1 * q[0][1] + e2 * q[0][2];
  b1 = e0 * q[1][0] + e1 * q[1][1] + e2 * q[1][2];
  b2 = e0 * q[2][0] + e1 * q[2][1] + e2 * q[2][2];
}

// Shades eight pixels of one triangle from their exact edge values e0..e2, writing the lanes in
// `mine` to the scratch buffers at i: eight pixels of a row, or with kPairs four pixels of row i
// and four of the row below.
template <bool kPairs, typename P>
SR_INLINE void shade_group(const P& t, f8 e0, f8 e1, f8 e2, i8 mine, int i, ShadeScratch& out) {
  constexpr bool kLit = P::kKind == KernelKind::Lit;
  const ShadeTriangle& s = t.s;
  const ShadeConstants& c = t.c;
  const uint16_t work = t.work;
  if (work & (kWorkVaryingColor | kWorkVaryingNormal)) {
    if (work & kWorkExactNormal) {  // the normal output's own interpolation, at the exact weights
      f8 q0, q1, q2;
      exact_weights(s.q, e0, e1, e2, q0, q1, q2);
      Lanes3 m = weighted(s.normal, q0, q1, q2);  // (a positive multiple: normalised)
      normalize(m.x, m.y, m.z);
      merge<kPairs>(out.normal[0] + i, m.x, mine);
      merge<kPairs>(out.normal[1] + i, m.y, mine);
      merge<kPairs>(out.normal[2] + i, m.z, mine);
    }
    // The normal output below unless it was exact above.
    const bool normal_out = (work & kWorkVaryingNormal) && !(work & kWorkExactNormal);
    if ((work & kWorkVaryingColor) || normal_out) {
      // Perspective-correct barycentrics from the exact edge values: the snapped triangle's, or
      // the exact weights.
      f8 b0, b1, b2;
      if (kLit && (work & kWorkExactWeights)) {
        exact_weights(s.q, e0, e1, e2, b0, b1, b2);
      } else {
        b0 = e0 * c.persp[0]; b1 = e1 * c.persp[1]; b2 = e2 * c.persp[2];
      }
      const f8 inv_sum = 1.0f / (b0 + b1 + b2);
      b0 *= inv_sum; b1 *= inv_sum; b2 *= inv_sum;
      Fragment frag;
      f8& nx = frag.normal[0];
      f8& ny = frag.normal[1];
      f8& nz = frag.normal[2];
      nx = ny = nz = f8{};
      const bool varying_color = work & kWorkVaryingColor;
      if (normal_out || (varying_color && (s.reads & ShadeTriangle::kReadNormal))) {
        const Lanes3 n = weighted(s.normal, b0, b1, b2);
        nx = n.x; ny = n.y; nz = n.z;
        // The tile's light pass normalises the normals it is left (ShadeScratch::lit_code), in
        // full groups of eight: the same operations on the same values.
        if (!kLit || (work & kWorkNormalOut) || !c.raw_normal) normalize(nx, ny, nz);
      }
      if (normal_out) {
        merge<kPairs>(out.normal[0] + i, nx, mine);
        merge<kPairs>(out.normal[1] + i, ny, mine);
        merge<kPairs>(out.normal[2] + i, nz, mine);
      }
      if (varying_color) {
        f8 r{}, g{}, b{};
        if (s.reads & ShadeTriangle::kReadColor) {
          if (s.uniform_color) {
            r = splat(s.color[0].x); g = splat(s.color[0].y); b = splat(s.color[0].z);
          } else {
            const Lanes3 rgb = weighted(s.color, b0, b1, b2);
            r = rgb.x; g = rgb.y; b = rgb.z;
          }
        }
        if (kLit && (s.reads & ShadeTriangle::kReadPosition)) {
          const Lanes3 pos = weighted(s.position, b0, b1, b2);
          frag.position[0] = pos.x; frag.position[1] = pos.y; frag.position[2] = pos.z;
        }
        if (kLit && (s.reads & ShadeTriangle::kReadUv)) {
          for (int j = 0; j < 2; ++j)
            frag.attr[j] = b0 * s.attr[0][j] + b1 * s.attr[1][j] + b2 * s.attr[2][j];
          if (s.reads & ShadeTriangle::kReadUvDerivs)
            for (int j = 0; j < 2; ++j) {
              frag.attr_dx[j] = (s.attr_dx[j] - frag.attr[j] * s.sum_dx) * inv_sum;
              frag.attr_dy[j] = (s.attr_dy[j] - frag.attr[j] * s.sum_dy) * inv_sum;
            }
        }
        frag.mine = mine;
        if (kLit && c.code != 0) {  // the tile's light pass lights it from these
          f8 n[3] = {nx, ny, nz};
          if (c.textured) c.kernels->surface(c, frag, n, r, g, b);
          for (int k = 0; k < 3; ++k) merge<kPairs>(out.lit_normal[k] + i, n[k] * c.side, mine);
          if (c.code & 1)
            for (int k = 0; k < 3; ++k) merge<kPairs>(out.lit_position[k] + i, frag.position[k], mine);
          out.lit_pending = true;
        } else if (kLit && c.op == ShadeConstants::kOutOfLine) {
          c.kernels->shade(c, frag, r, g, b);
        } else {
          shade_inline<P::kKind>(c, frag, r, g, b);
        }
        merge<kPairs>(out.rgb[0] + i, r, mine);
        merge<kPairs>(out.rgb[1] + i, g, mine);
        merge<kPairs>(out.rgb[2] + i, b, mine);
      }
      if (kLit && (work & kWorkShadingNormal)) {  // the normal output as the shading perturbs it
        if (!varying_color) {  // (the colour's block computes the uvs otherwise)
          for (int j = 0; j < 2; ++j) {
            frag.attr[j] = b0 * s.attr[0][j] + b1 * s.attr[1][j] + b2 * s.attr[2][j];
            frag.attr_dx[j] = (s.attr_dx[j] - frag.attr[j] * s.sum_dx) * inv_sum;
            frag.attr_dy[j] = (s.attr_dy[j] - frag.attr[j] * s.sum_dy) * inv_sum;
          }
          frag.mine = mine;
        }
        f8 n[3] = {nx, ny, nz};
        c.kernels->shading_normal(c, frag, n);
        for (int k = 0; k < 3; ++k) merge<kPairs>(out.normal[k] + i, n[k], mine);
      }
    }
  }
  if (work & kWorkUnitNormal)
    for (int k = 0; k < 3; ++k) merge<kPairs>(out.normal[k] + i, splat(s.unit_normal[k]), mine);
  if (work & kWorkColor) {
    if (s.color_kind == ShadeTriangle::kConstantColor) {
      for (int k = 0; k < 3; ++k) merge<kPairs>(out.rgb[k] + i, splat(s.rgb[k]), mine);
    } else if (s.color_kind == ShadeTriangle::kUniformLit) {
      // Unnormalised perspective weights: the normal's length and dot(n, L) share their scale.
      f8 b0, b1, b2;
      if (kLit && (work & kWorkExactWeights)) {
        exact_weights(s.q, e0, e1, e2, b0, b1, b2);
      } else {
        b0 = e0 * c.persp[0]; b1 = e1 * c.persp[1]; b2 = e2 * c.persp[2];
      }
      const f8 f = shade_uniform(c, s, b0, b1, b2);
      for (int k = 0; k < 3; ++k) merge<kPairs>(out.rgb[k] + i, f * s.color[0][k], mine);
    }
    if (kLit && (work & kWorkLitCode))  // (with normals requested they are unit already)
      merge<kPairs>(out.lit_code + i, splat(work & kWorkNormalOut ? c.code & ~2 : c.code), mine);
  }
}

// Shades the pixels of rows [y0, y1], columns [x0, x1] of the tile that visible triangle `index`
// owns, into the scratch buffers.
template <typename P, typename Edges>
SR_INLINE void shade_pixels(const P& t, Edges edges, int x0, int x1, int y0, int y1,
                            const TileRect& rect, const TileScratch& raster, uint32_t index,
                            ShadeScratch& out) {
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const int width = x1 - x0 + 1;
  for (int y = y0; y <= y1; ++y, edges.next_row()) {
    int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    typename Edges::Cursor cursor = edges.cursor();
    for (int dx = 0; dx < width; dx += kLanes, i += kLanes, cursor.next(edges)) {
      const i8 mine = (load<i8>(raster.visible + i) == index_v) & (lane < width - dx);
      if (any(mine))
        shade_group<false>(t, cursor.edge(0), cursor.edge(1), cursor.edge(2),
                                            mine, i, out);
    }
  }
}

// The same for a small triangle whose box is at most four pixels wide, two rows at a time.
template <typename P>
SR_INLINE void shade_pairs(const P& t, SmallEdgePairs edges, int x0, int x1, int y0,
                           int y1, const TileRect& rect, const TileScratch& raster, uint32_t index,
                           ShadeScratch& out) {
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const i8 in_box_x = (lane & 3) < x1 - x0 + 1, row = lane >> 2;
  for (int y = y0; y <= y1; y += 2, edges.next_rows()) {
    const int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    const i8 mine = (raster::load_lanes<true, i8>(raster.visible + i) == index_v) & in_box_x &
                    (row < y1 - y + 1);
    if (any(mine))
      shade_group<true>(t, edges.edge(0), edges.edge(1), edges.edge(2), mine, i,
                                         out);
  }
}

// Shades the pixels of `raster` that visible triangle `index` owns, the triangle prepared: its
// edges are evaluated at the raster's sample offset.
template <typename P>
SR_INLINE void shade_prepared(const TileRect& rect, const TileScratch& raster, uint32_t index,
                              const P& p, ShadeScratch& out) {
  const TriangleSetup& t = *raster.triangles[index].tri;
  const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
  const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
  const EdgeEquations eq = edge_equations(t, x0, y0, raster);
  if (is_small(t) && x1 - x0 < 4 && y1 > y0)
    shade_pairs(p, SmallEdgePairs(eq), x0, x1, y0, y1, rect, raster, index, out);
  else if (is_small(t))
    shade_pixels(p, SmallEdges(eq), x0, x1, y0, y1, rect, raster, index, out);
  else
    shade_pixels(p, LargeEdges(eq), x0, x1, y0, y1, rect, raster, index, out);
}

// shade_prepared in each of the passes (the `owned` ones) a small triangle owns pixels in, in one
// walk (walk_small_box; each pass's exact edge values by edge_offset), so the same shades.
template <bool kPairs, typename P>
struct PassShades {
  const int32_t (*offset)[3];
  i8 index_v;
  const TileScratch* const* rasters;
  ShadeScratch* const* outs;
  const int* owned;
  int count;
  const P& t;
  SR_INLINE void run(const i8 (&e0)[3], int i, i8 in_box) {
    for (int j = 0; j < count; ++j) {
      const TileScratch& raster = *rasters[owned[j]];
      const i8 mine = (raster::load_lanes<kPairs, i8>(raster.visible + i) == index_v) & in_box;
      if (any(mine))
        shade_group<kPairs>(t, to_float(e0[0] + offset[j][0]),
                                             to_float(e0[1] + offset[j][1]),
                                             to_float(e0[2] + offset[j][2]), mine, i,
                                             *outs[owned[j]]);
    }
  }
};

template <bool kPairs, typename P>
SR_INLINE void shade_small_passes(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                                  const TileRect& rect, const TileScratch* const* rasters,
                                  ShadeScratch* const* outs, const int* owned, int count,
                                  uint32_t index, const P& p) {
  const EdgeEquations eq = edge_equations(t, x0, y0, *rasters[owned[0]]);
  int32_t offset[kMaxShadePasses][3];
  for (int j = 0; j < count; ++j) raster::edge_offset(t, x0, y0, eq, *rasters[owned[j]], offset[j]);
  PassShades<kPairs, P> shades{offset, splat(int32_t(index)), rasters, outs, owned, count, p};
  raster::walk_small_box<kPairs>(eq, x0, x1, y0, y1, rect, shades);
}

template <KernelKind K>
SR_INLINE void shade_triangle(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                              uint32_t index, ShadeScratch& out) {
  Prepared<K> t;
  PrepareCaches caches;
  t.make(p, raster.triangles[index], caches);
  shade_prepared(rect, raster, index, t, out);
}

// Deferred shading: each triangle that owns a pixel of the tile, once, over the pixels it owns,
// for each of `passes` raster passes of the tile (msaa's samples, each into its own scratch;
// one pass otherwise). The passes binned the same triangles: a triangle is prepared once for all
// the passes it owns pixels of.
template <KernelKind K>
struct ShadeVisible {
  static constexpr bool kLit = K == KernelKind::Lit;
  SR_INLINE static void run(const ShadeParams& p, const TileRect& rect,
                            const TileScratch* const* rasters, ShadeScratch* const* outs,
                            int passes) {
    // Per triangle and pass, whether it owns a pixel (a byte each, written without reading):
    // eight entries at a time, groups with none skipped (an msaa pass other than the first owns
    // few pixels), the rest marked without branches (an empty entry marks the spare last slot).
    constexpr int kStride = kMaxShadePasses;
    const uint32_t n = uint32_t(rasters[0]->triangles.size());
    std::vector<uint8_t>& used = outs[0]->used;
    used.assign(std::size_t(n + 1) * kStride, 0);
    const i8 none = splat(int32_t(kNoTriangle)), lane = lane_index();
    const int width = rect.x1 - rect.x0;
    for (int k = 0; k < passes; ++k) {
      uint8_t* const mark = used.data() + k;
      for (int y = rect.y0; y < rect.y1; ++y) {
        const uint32_t* visible = rasters[k]->visible + (y - rect.y0) * kTileSizePx;
        for (int x = 0; x < width; x += kLanes) {
          const i8 v = lane < width - x ? load<i8>(visible + x) : none;
          if (!any(v != none)) continue;
          for (int l = 0; l < kLanes; ++l)
            mark[std::size_t(std::min(x + l < width ? visible[x + l] : kNoTriangle, n)) * kStride] = 1;
        }
      }
    }
    Prepared<K> prepared;  // (one for all, with its caches)
    PrepareCaches caches;
    for (uint32_t v = 0; v < n; ++v) {
      const uint8_t* const owns = used.data() + std::size_t(v) * kStride;
      uint32_t any_pass;
      std::memcpy(&any_pass, owns, sizeof any_pass);
      if (!any_pass) continue;
      prepared.make(p, rasters[0]->triangles[v], caches);
      int owned[kMaxShadePasses], count = 0;
      for (int k = 0; k < passes; ++k)
        if (owns[k]) owned[count++] = k;
      const TriangleSetup& t = *rasters[0]->triangles[v].tri;
      if (count > 1 && is_small(t)) {  // one walk for all of its passes
        const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
        const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
        if (x1 - x0 < 4 && y1 > y0)
          shade_small_passes<true>(t, x0, x1, y0, y1, rect, rasters, outs, owned,
                                                    count, v, prepared);
        else
          shade_small_passes<false>(t, x0, x1, y0, y1, rect, rasters, outs,
                                                     owned, count, v, prepared);
        continue;
      }
      for (int j = 0; j < count; ++j)
        shade_prepared(rect, *rasters[owned[j]], v, prepared, *outs[owned[j]]);
    }
    if (kLit && p.in.defers_light)
      for (int k = 0; k < passes; ++k) p.lit->light_tile(p, rect, *rasters[k], *outs[k]);
  }
};

// Forward shading: the raster kernels' hook (rasterize.hpp) that shades the lanes a triangle wins
// as it wins them, preparing the triangle on its first win. Triangles on the int64 raster path
// are noted and shaded afterwards, from the visibility buffer, as in deferred shading. A pixel
// overwritten later was shaded in vain (overdraw); its final value is the same either way, since
// a pixel's shade depends only on the triangle and the pixel.
template <KernelKind K>
struct ForwardShading {
  static constexpr bool kShades = true;
  const ShadeParams& p;
  ShadeScratch& out;
  const VisibleTriangle* current = nullptr;  // valid until the next triangle()
  bool ready = false;
  Prepared<K> t{};
  PrepareCaches caches{};  // (t's)

  SR_INLINE void triangle(const VisibleTriangle& vt) {
    current = &vt;
    ready = false;
  }
  template <bool kPairs>
  SR_INLINE void shade(i8 win, int i, f8 e0, f8 e1, f8 e2) {
    if (!ready) {
      t.make(p, *current, caches);
      ready = true;
    }
    shade_group<kPairs>(t, e0, e1, e2, win, i, out);
  }
  SR_INLINE void large_won(uint32_t index) { out.large.push_back(index); }
  // What prepare() will read of record i's vertices (raster::rasterize_all).
  SR_INLINE void prefetch_attributes(const SetupChunk& chunk, uint32_t i) {
    const TriangleShading& a = chunk.shading[i];
    if (a.clip_ref != kNoClip) return;
    const ShadeDraw& d = p.draws[chunk.records[i].draw];
    if (d.world_normals)
      for (int k = 0; k < 3; ++k) __builtin_prefetch(d.world_normals + a.vertex[k]);
    if (p.color && !d.mesh->colors.empty())
      for (int k = 0; k < 3; ++k) __builtin_prefetch(d.mesh->colors.data() + a.vertex[k]);
  }
};

// (Not compiled with coverage counting: a render that counts coverage, a diagnostic, takes the
// deferred path, which gives the same bits; one kernel less per output set.)
template <KernelKind K>
struct ForwardTile {
  static constexpr bool kLit = K == KernelKind::Lit;
  SR_INLINE static void run(const ShadeParams& p, const TileRect& rect, int tile,
                            const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                            TileScratch& raster, ShadeScratch& scratch) {
    scratch.large.clear();
    ForwardShading<K> hook{p, scratch};
    raster::rasterize_all<false>(rect, tile, chunks, num_chunks, raster, hook);
    for (const uint32_t index : scratch.large)
      shade_triangle<K>(p, rect, raster, index, scratch);
    if (kLit && p.in.defers_light) p.lit->light_tile(p, rect, raster, scratch);
  }
};

// The kernel of one path for one instruction set and KernelKind. Each is defined in its kernel file
// (shade_kernels_*.cpp: the lit kernel, and the plain ones together).
template <Isa I, KernelKind K>
TileKernels::Deferred deferred_kernel();
template <Isa I, KernelKind K>
TileKernels::Forward forward_kernel();
#define SR_DECLARE_KERNELS(I, K)                  \
  template <>                                     \
  TileKernels::Deferred deferred_kernel<I, K>();  \
  template <>                                     \
  TileKernels::Forward forward_kernel<I, K>();
#define SR_DECLARE_KINDS(I)                           \
  SR_DECLARE_KERNELS(I, KernelKind::Lit)              \
  SR_DECLARE_KERNELS(I, KernelKind::Headlight)        \
  SR_DECLARE_KERNELS(I, KernelKind::Unlit)            \
  SR_DECLARE_KERNELS(I, KernelKind::NormalColor)
SR_DECLARE_KINDS(Isa::Generic)
#if SR_X86
SR_DECLARE_KINDS(Isa::Avx2)
#endif
#undef SR_DECLARE_KINDS
#undef SR_DECLARE_KERNELS

// The definitions, in a kernel file.
#define SR_DEFINE_KERNEL(path, I, K, Kernel, Fn)                 \
  template <>                                                    \
  Fn path##_kernel<I, K>() {                                     \
    return dispatch::IsaKernel<Kernel<K>, Fn>::template get<I>(); \
  }

}  // namespace shading
}  // namespace sr
