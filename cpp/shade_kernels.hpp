// Shading kernels: the deferred walk and the forward hook over a tile, templated on the sample
// pattern, the shading model and which outputs are written. Included by one file per
// instruction set (shade_avx2.cpp, shade_generic.cpp), which instantiates them for it: the two
// compile in parallel (under the sanitizers each takes minutes).
#pragma once

#include "dispatch.hpp"
#include "interpolate.hpp"
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

// Per-triangle constants of shade_group: the perspective weights and the model's own.
template <typename Model>
struct ShadeConstants {
  f8 persp[3];
  typename Model::Constants model;
  ShadeConstants() = default;
  SR_INLINE ShadeConstants(const ShadeParams& p, const ShadeTriangle<Model>& s) : model(p.in, s) {
    for (int k = 0; k < 3; ++k) persp[k] = splat(s.persp[k]);
  }
};

// Shades eight pixels of one triangle from their exact edge values e0..e2, writing the lanes in
// `mine` to the scratch buffers at i: eight pixels of a row, or with kPairs four pixels of row i
// and four of the row below.
template <typename Model, bool kColor, bool kNormal, bool kPairs>
SR_INLINE void shade_group(const ShadeTriangle<Model>& s, const ShadeConstants<Model>& c, f8 e0,
                           f8 e1, f8 e2, i8 mine, int i, ShadeScratch& out) {
  const auto merge = [&](auto* p, auto v) {
    raster::store_lanes<kPairs>(p, mine ? v : raster::load_lanes<kPairs, decltype(v)>(p));
  };
  const bool varying_color = kColor && s.color_kind == ShadeTriangleBase::kVaryingColor;
  const bool varying_normal = kNormal && !s.one_normal;
  if (varying_color || varying_normal) {
    // Perspective-correct barycentrics from the exact edge values.
    f8 b0 = e0 * c.persp[0], b1 = e1 * c.persp[1], b2 = e2 * c.persp[2];
    const f8 inv_sum = 1.0f / (b0 + b1 + b2);
    b0 *= inv_sum; b1 *= inv_sum; b2 *= inv_sum;
    Fragment<Model> frag;
    f8& nx = frag.normal[0];
    f8& ny = frag.normal[1];
    f8& nz = frag.normal[2];
    nx = ny = nz = f8{};
    if (varying_normal ||
        (Model::kReadsNormal && varying_color && (s.reads & ShadeTriangleBase::kReadNormal))) {
      const Lanes3 n = weighted(s.normal, b0, b1, b2);
      nx = n.x; ny = n.y; nz = n.z;
      // The tile's light pass normalises the normals it is left (ShadeScratch::lit_code), in
      // full groups of eight: the same operations on the same values.
      bool raw = false;
      if constexpr (DefersLight<Model>::value && !kNormal) raw = c.model.raw_normal;
      if (!raw) normalize(nx, ny, nz);
    }
    if (varying_normal) {
      merge(out.normal[0] + i, nx);
      merge(out.normal[1] + i, ny);
      merge(out.normal[2] + i, nz);
    }
    if (varying_color) {
      f8 r{}, g{}, b{};
      if constexpr (Model::kReadsColor) {
        bool uniform = false;  // (the lit model's flag: see prepare)
        if constexpr (DefersLight<Model>::value) uniform = s.uniform_color;
        if (uniform) {
          r = splat(s.color[0].x); g = splat(s.color[0].y); b = splat(s.color[0].z);
        } else {
          const Lanes3 rgb = weighted(s.color, b0, b1, b2);
          r = rgb.x; g = rgb.y; b = rgb.z;
        }
      }
      if constexpr (Model::kReadsPosition) {
        if (s.reads & ShadeTriangleBase::kReadPosition) {
          const Lanes3 pos = weighted(s.position, b0, b1, b2);
          frag.position[0] = pos.x; frag.position[1] = pos.y; frag.position[2] = pos.z;
        }
      }
      if constexpr (Model::kAttributes > 0) {
        if (s.reads & ShadeTriangleBase::kReadUv) {
          for (int j = 0; j < Model::kAttributes; ++j)
            frag.attr[j] = b0 * s.attr[0][j] + b1 * s.attr[1][j] + b2 * s.attr[2][j];
          if (s.reads & ShadeTriangleBase::kReadUvDerivs)
            for (int j = 0; j < Model::kAttributes; ++j) {
              frag.attr_dx[j] = (s.attr_dx[j] - frag.attr[j] * s.sum_dx) * inv_sum;
              frag.attr_dy[j] = (s.attr_dy[j] - frag.attr[j] * s.sum_dy) * inv_sum;
            }
        }
      }
      frag.mine = mine;
      bool deferred = false;
      if constexpr (DefersLight<Model>::value) {
        if (c.model.code != 0) {  // the tile's light pass lights it from these
          f8 n[3];
          Model::surface(c.model, frag, n, r, g, b);
          for (int k = 0; k < 3; ++k) merge(out.lit_normal[k] + i, n[k]);
          if (c.model.code & 1)
            for (int k = 0; k < 3; ++k) merge(out.lit_position[k] + i, frag.position[k]);
          out.lit_pending = true;
          deferred = true;
        }
      }
      if (!deferred) Model::shade(c.model, frag, r, g, b);
      merge(out.rgb[0] + i, r);
      merge(out.rgb[1] + i, g);
      merge(out.rgb[2] + i, b);
    }
  }
  if constexpr (kNormal) {
    if (!varying_normal)
      for (int k = 0; k < 3; ++k) merge(out.normal[k] + i, splat(s.unit_normal[k]));
  }
  if constexpr (kColor) {
    if (s.color_kind == ShadeTriangleBase::kConstantColor) {
      for (int k = 0; k < 3; ++k) merge(out.rgb[k] + i, splat(s.rgb[k]));
    } else if constexpr (Model::kUniformLit) {
      if (s.color_kind == ShadeTriangleBase::kUniformLit) {
        // Unnormalised perspective weights: the normal's length and dot(n, L) share their scale.
        const f8 b0 = e0 * c.persp[0], b1 = e1 * c.persp[1], b2 = e2 * c.persp[2];
        const f8 f = Model::shade_uniform(c.model, s, b0, b1, b2);
        for (int k = 0; k < 3; ++k) merge(out.rgb[k] + i, f * s.color[0][k]);
      }
    }
    if constexpr (DefersLight<Model>::value)  // (with normals requested they are unit already)
      merge(out.lit_code + i, splat(kNormal ? c.model.code & ~2 : c.model.code));
  }
}

// The lit model's light pass over a tile: the pixels whose triangles left their lighting to it
// (ShadeScratch::lit_code) are lit eight at a time, whichever triangles they belong to, with
// each lane's own draw's material: the same formulas on the same values as Model::shade, so the
// same bits, with every lane of a group in use where small triangles fill a few of each.
template <typename Model>
SR_INLINE void light_tile(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                          ShadeScratch& out) {
  if (!out.lit_pending) return;
  out.lit_pending = false;
  const i8 lane = lane_index(), none = splat(int32_t(kNoTriangle));
  const int width = rect.x1 - rect.x0;
  for (int y = rect.y0; y < rect.y1; ++y) {
    const int row = (y - rect.y0) * kTileSizePx;
    for (int x = 0; x < width; x += kLanes) {
      const int i = row + x;
      const i8 code = load<i8>(out.lit_code + i);
      i8 pending = (code != 0) & (load<i8>(raster.visible + i) != none) & (lane < width - x);
      if (!any(pending)) continue;
      f8 n[3], position[3], base[3], rgb[3];
      for (int k = 0; k < 3; ++k) {
        n[k] = load<f8>(out.lit_normal[k] + i);
        position[k] = load<f8>(out.lit_position[k] + i);
        base[k] = rgb[k] = load<f8>(out.rgb[k] + i);
      }
      const i8 raw = pending & ((code & 2) != 0);  // normals left to normalise here
      if (any(raw)) {
        f8 u[3] = {n[0], n[1], n[2]};
        normalize(u[0], u[1], u[2]);
        for (int k = 0; k < 3; ++k) n[k] = raw ? u[k] : n[k];
      }
      do {  // one draw's lanes at a time (one pass but at a material's edge)
        int32_t first = 0;
        for (int l = 0; l < kLanes; ++l)
          if (pending[l]) { first = code[l]; break; }
        const i8 mine = pending & (code == first);
        const Material& m = p.draws[(first >> 2) - 1].material;
        f8 o[3];
        if (first & 1)
          lit_radiance<true>(p.in.lit, m, m.brdf, n, position, base, o);
        else
          lit_radiance<false>(p.in.lit, m, m.brdf, n, position, base, o);
        for (int k = 0; k < 3; ++k) rgb[k] = mine ? o[k] : rgb[k];
        pending = pending & ~mine;
      } while (any(pending));
      for (int k = 0; k < 3; ++k) store(out.rgb[k] + i, rgb[k]);
    }
  }
}

// Shades the pixels of rows [y0, y1], columns [x0, x1] of the tile that visible triangle `index`
// owns, into the scratch buffers.
template <typename Model, bool kColor, bool kNormal, typename Edges>
SR_INLINE void shade_pixels(const ShadeTriangle<Model>& s, const ShadeConstants<Model>& c,
                            Edges edges, int x0, int x1, int y0, int y1, const TileRect& rect,
                            const TileScratch& raster, uint32_t index, ShadeScratch& out) {
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const int width = x1 - x0 + 1;
  for (int y = y0; y <= y1; ++y, edges.next_row()) {
    int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    typename Edges::Cursor cursor = edges.cursor();
    for (int dx = 0; dx < width; dx += kLanes, i += kLanes, cursor.next(edges)) {
      const i8 mine = (load<i8>(raster.visible + i) == index_v) & (lane < width - dx);
      if (any(mine))
        shade_group<Model, kColor, kNormal, false>(s, c, cursor.edge(0), cursor.edge(1),
                                                   cursor.edge(2), mine, i, out);
    }
  }
}

// The same for a small triangle whose box is at most four pixels wide, two rows at a time.
template <typename Model, bool kColor, bool kNormal>
SR_INLINE void shade_pairs(const ShadeTriangle<Model>& s, const ShadeConstants<Model>& c,
                           SmallEdgePairs edges, int x0, int x1, int y0, int y1,
                           const TileRect& rect, const TileScratch& raster, uint32_t index,
                           ShadeScratch& out) {
  const i8 lane = lane_index(), index_v = splat(int32_t(index));
  const i8 in_box_x = (lane & 3) < x1 - x0 + 1, row = lane >> 2;
  for (int y = y0; y <= y1; y += 2, edges.next_rows()) {
    const int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    const i8 mine = (raster::load_lanes<true, i8>(raster.visible + i) == index_v) & in_box_x &
                    (row < y1 - y + 1);
    if (any(mine))
      shade_group<Model, kColor, kNormal, true>(s, c, edges.edge(0), edges.edge(1),
                                                edges.edge(2), mine, i, out);
  }
}

// Shades the pixels of `raster` that visible triangle `index` owns, the triangle prepared (s, c):
// its edges are evaluated at the raster's sample offset.
template <typename Model, bool kColor, bool kNormal>
SR_INLINE void shade_prepared(const TileRect& rect, const TileScratch& raster, uint32_t index,
                              const ShadeTriangle<Model>& s, const ShadeConstants<Model>& c,
                              ShadeScratch& out) {
  const TriangleSetup& t = *raster.triangles[index].tri;
  const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
  const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
  const EdgeEquations eq = edge_equations(t, x0, y0, raster);
  if (is_small(t) && x1 - x0 < 4 && y1 > y0)
    shade_pairs<Model, kColor, kNormal>(s, c, SmallEdgePairs(eq), x0, x1, y0, y1, rect, raster,
                                        index, out);
  else if (is_small(t))
    shade_pixels<Model, kColor, kNormal>(s, c, SmallEdges(eq), x0, x1, y0, y1, rect, raster,
                                         index, out);
  else
    shade_pixels<Model, kColor, kNormal>(s, c, LargeEdges(eq), x0, x1, y0, y1, rect, raster,
                                         index, out);
}

// shade_prepared in each of the passes (the `owned` ones) a small triangle owns pixels in, in one
// walk (walk_small_box; each pass's exact edge values by edge_offset), so the same shades.
template <typename Model, bool kColor, bool kNormal, bool kPairs>
struct PassShades {
  const int32_t (*offset)[3];
  i8 index_v;
  const TileScratch* const* rasters;
  ShadeScratch* const* outs;
  const int* owned;
  int count;
  const ShadeTriangle<Model>& s;
  const ShadeConstants<Model>& c;
  SR_INLINE void run(const i8 (&e0)[3], int i, i8 in_box) {
    for (int j = 0; j < count; ++j) {
      const TileScratch& raster = *rasters[owned[j]];
      const i8 mine = (raster::load_lanes<kPairs, i8>(raster.visible + i) == index_v) & in_box;
      if (any(mine))
        shade_group<Model, kColor, kNormal, kPairs>(
            s, c, to_float(e0[0] + offset[j][0]), to_float(e0[1] + offset[j][1]),
            to_float(e0[2] + offset[j][2]), mine, i, *outs[owned[j]]);
    }
  }
};

template <typename Model, bool kColor, bool kNormal, bool kPairs>
SR_INLINE void shade_small_passes(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                                  const TileRect& rect, const TileScratch* const* rasters,
                                  ShadeScratch* const* outs, const int* owned, int count,
                                  uint32_t index, const ShadeTriangle<Model>& s,
                                  const ShadeConstants<Model>& c) {
  const EdgeEquations eq = edge_equations(t, x0, y0, *rasters[owned[0]]);
  int32_t offset[kMaxShadePasses][3];
  for (int j = 0; j < count; ++j) raster::edge_offset(t, x0, y0, eq, *rasters[owned[j]], offset[j]);
  PassShades<Model, kColor, kNormal, kPairs> shades{
      offset, splat(int32_t(index)), rasters, outs, owned, count, s, c};
  raster::walk_small_box<kPairs>(eq, x0, x1, y0, y1, rect, shades);
}

template <typename Pattern, typename Model, bool kColor, bool kNormal>
SR_INLINE void shade_triangle(const ShadeParams& p, const TileRect& rect, const TileScratch& raster,
                              uint32_t index, ShadeScratch& out) {
  ShadeTriangle<Model> s;
  prepare<Model, Model::kReadsNormal || kNormal>(p, raster.triangles[index], s);
  shade_prepared<Model, kColor, kNormal>(rect, raster, index, s, ShadeConstants<Model>(p, s), out);
}

// Deferred shading: each triangle that owns a pixel of the tile, once, over the pixels it owns,
// for each of `passes` raster passes of the tile (msaa's samples, each into its own scratch;
// one pass otherwise). The passes binned the same triangles: a triangle is prepared once for all
// the passes it owns pixels of.
template <typename Pattern, typename Model, bool kColor, bool kNormal>
struct ShadeVisible {
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
    for (uint32_t v = 0; v < n; ++v) {
      const uint8_t* const owns = used.data() + std::size_t(v) * kStride;
      uint32_t any_pass;
      std::memcpy(&any_pass, owns, sizeof any_pass);
      if (!any_pass) continue;
      ShadeTriangle<Model> s;
      prepare<Model, Model::kReadsNormal || kNormal>(p, rasters[0]->triangles[v], s);
      const ShadeConstants<Model> c(p, s);
      int owned[kMaxShadePasses], count = 0;
      for (int k = 0; k < passes; ++k)
        if (owns[k]) owned[count++] = k;
      const TriangleSetup& t = *rasters[0]->triangles[v].tri;
      if (count > 1 && is_small(t)) {  // one walk for all of its passes
        const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
        const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
        if (x1 - x0 < 4 && y1 > y0)
          shade_small_passes<Model, kColor, kNormal, true>(t, x0, x1, y0, y1, rect, rasters, outs,
                                                           owned, count, v, s, c);
        else
          shade_small_passes<Model, kColor, kNormal, false>(t, x0, x1, y0, y1, rect, rasters,
                                                            outs, owned, count, v, s, c);
        continue;
      }
      for (int j = 0; j < count; ++j)
        shade_prepared<Model, kColor, kNormal>(rect, *rasters[owned[j]], v, s, c,
                                               *outs[owned[j]]);
    }
    if constexpr (kColor && DefersLight<Model>::value)
      for (int k = 0; k < passes; ++k) light_tile<Model>(p, rect, *rasters[k], *outs[k]);
  }
};

// Forward shading: the raster kernels' hook (rasterize.hpp) that shades the lanes a triangle wins
// as it wins them, preparing the triangle on its first win. Triangles on the int64 raster path
// are noted and shaded afterwards, from the visibility buffer, as in deferred shading. A pixel
// overwritten later was shaded in vain (overdraw); its final value is the same either way, since
// a pixel's shade depends only on the triangle and the pixel.
template <typename Model, bool kColor, bool kNormal>
struct ForwardShading {
  static constexpr bool kShades = true;
  const ShadeParams& p;
  ShadeScratch& out;
  const VisibleTriangle* current = nullptr;  // valid until the next triangle()
  bool ready = false;
  ShadeTriangle<Model> s{};
  ShadeConstants<Model> c{};

  SR_INLINE void triangle(const VisibleTriangle& vt) {
    current = &vt;
    ready = false;
  }
  template <bool kPairs>
  SR_INLINE void shade(i8 win, int i, f8 e0, f8 e1, f8 e2) {
    if (!ready) {
      prepare<Model, Model::kReadsNormal || kNormal>(p, *current, s);
      c = ShadeConstants<Model>(p, s);
      ready = true;
    }
    shade_group<Model, kColor, kNormal, kPairs>(s, c, e0, e1, e2, win, i, out);
  }
  SR_INLINE void large_won(uint32_t index) { out.large.push_back(index); }
  // What prepare() will read of record i's vertices (raster::rasterize_all).
  SR_INLINE void prefetch_attributes(const SetupChunk& chunk, uint32_t i) {
    const TriangleShading& a = chunk.shading[i];
    if (a.clip_ref != kNoClip) return;
    const ShadeDraw& d = p.draws[chunk.records[i].draw];
    if constexpr (Model::kReadsNormal || kNormal)
      if (d.world_normals)
        for (int k = 0; k < 3; ++k) __builtin_prefetch(d.world_normals + a.vertex[k]);
    if constexpr (kColor && Model::kReadsColor)
      if (!d.mesh->colors.empty())
        for (int k = 0; k < 3; ++k) __builtin_prefetch(d.mesh->colors.data() + a.vertex[k]);
  }
};

// (Not compiled with coverage counting: a render that counts coverage, a diagnostic, takes the
// deferred path, which gives the same bits; one kernel less per model and output set.)
template <typename Pattern, typename Model, bool kColor, bool kNormal>
struct ForwardTile {
  SR_INLINE static void run(const ShadeParams& p, const TileRect& rect, int tile,
                            const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                            TileScratch& raster, ShadeScratch& scratch) {
    scratch.large.clear();
    ForwardShading<Model, kColor, kNormal> hook{p, scratch};
    raster::rasterize_all<Pattern, false>(rect, tile, chunks, num_chunks, raster, hook);
    for (const uint32_t index : scratch.large)
      shade_triangle<Pattern, Model, kColor, kNormal>(p, rect, raster, index, scratch);
    if constexpr (kColor && DefersLight<Model>::value) light_tile<Model>(p, rect, raster, scratch);
  }
};

// The kernels of instruction set I for one render's choices (shade_avx2.cpp, shade_generic.cpp).
// Without colour the model is moot (normals only: the unlit instantiation); with neither colour
// nor normals there is nothing to shade (null).
template <Isa I>
TileKernels::Deferred select_deferred(const SamplePattern& pattern, Shading shading, bool color,
                                      bool normal);
template <Isa I>
TileKernels::Forward select_forward(const SamplePattern& pattern, Shading shading, bool color,
                                    bool normal);

// Each is defined in its instruction set's file.
template <>
TileKernels::Deferred select_deferred<Isa::Avx2>(const SamplePattern&, Shading, bool, bool);
template <>
TileKernels::Deferred select_deferred<Isa::Generic>(const SamplePattern&, Shading, bool, bool);
template <>
TileKernels::Forward select_forward<Isa::Avx2>(const SamplePattern&, Shading, bool, bool);
template <>
TileKernels::Forward select_forward<Isa::Generic>(const SamplePattern&, Shading, bool, bool);

// The definitions of both, for the file of instruction set I.
template <Isa I>
TileKernels::Deferred make_select_deferred(const SamplePattern& pattern, Shading shading,
                                           bool color, bool normal) {
  using Fn = TileKernels::Deferred;
  if (!color) shading = Shading::Unlit;
  return dispatch::select<Fn>(
      [](auto sp, auto m, auto c, auto n) -> Fn {
        if constexpr (!decltype(c)::value && !decltype(n)::value) {
          return nullptr;
        } else {
          using K = ShadeVisible<typename decltype(sp)::type, typename decltype(m)::type,
                                 decltype(c)::value, decltype(n)::value>;
          if constexpr (I == Isa::Avx2) return dispatch::IsaKernel<K, Fn>::avx2;
          else return dispatch::IsaKernel<K, Fn>::generic;
        }
      },
      pattern, shading, color, normal);
}

template <Isa I>
TileKernels::Forward make_select_forward(const SamplePattern& pattern, Shading shading,
                                         bool color, bool normal) {
  using Fn = TileKernels::Forward;
  if (!color) shading = Shading::Unlit;
  return dispatch::select<Fn>(
      [](auto sp, auto m, auto c, auto n) -> Fn {
        if constexpr (!decltype(c)::value && !decltype(n)::value) {
          return nullptr;
        } else {
          using K = ForwardTile<typename decltype(sp)::type, typename decltype(m)::type,
                                decltype(c)::value, decltype(n)::value>;
          if constexpr (I == Isa::Avx2) return dispatch::IsaKernel<K, Fn>::avx2;
          else return dispatch::IsaKernel<K, Fn>::generic;
        }
      },
      pattern, shading, color, normal);
}

}  // namespace shading
}  // namespace sr
