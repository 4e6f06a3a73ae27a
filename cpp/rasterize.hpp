// Rasterize stage: the per-tile hot loop. Steps integer edge functions, depth-tests, and records
// which triangle is visible at each pixel (a tile-local visibility buffer, shaded afterwards).
#pragma once

#include "alpha_mask.hpp"
#include "scanline.hpp"
#include "setup.hpp"
#include "simd.hpp"

#include <algorithm>
#include <limits>

namespace sr {

struct VisibleTriangle {
  const TriangleSetup* tri;
  const SetupChunk* chunk;  // owns tri, its TriangleShading and clip table
};
constexpr uint32_t kNoTriangle = 0xffffffffu;
constexpr int kTilePixels = kTileSizePx * kTileSizePx;

// Per-thread scratch, reused from tile to tile (row stride kTileSizePx). The kernels read and
// write eight pixels of a row, or four pixels of two rows, at a time from any pixel, so they may
// spill up to kLanes - 1 pixels into the next row or one row past the last (lanes masked off,
// values kept): the arrays have that much padding at the end.
// Allocate default-initialised (new TileScratch): clear() writes what a tile reads, so zeroing
// would only page-fault `coverage` in a first frame that does not ask for it.
constexpr int kTileScratchPixels = kTilePixels + kTileSizePx + simd::kLanes;
// The depth test's tie rule: a fragment wins only when its key exceeds the pixel's key times
// this factor (set per render), so a surface must be nearer by more than 2^-20 of its depth
// (about 1e-6) to hide one drawn before it. Keys of one plane computed from different triangles
// differ by rounding (a few units of float32's last place): coplanar geometry then keeps the
// triangle drawn first, as an exact tie does, instead of z-fighting. Perspective keys (1/w) are
// positive, orthographic ones (-depth) negative: each needs its own side of 1. -inf (nothing
// drawn) times either is -inf.
constexpr float kTieFactorPerspective = 1.0f + 0x1p-20f;
constexpr float kTieFactorOrthographic = 1.0f - 0x1p-20f;

struct TileScratch {
  float key[kTileScratchPixels];         // depth key of the nearest fragment so far (larger = closer)
  uint32_t visible[kTileScratchPixels];  // index into `triangles`, or kNoTriangle
  uint32_t coverage[kTileScratchPixels]; // fragments before the depth test
  std::vector<VisibleTriangle> triangles;  // binned triangles of this tile, in primitive order
  float tie = kTieFactorPerspective;      // the render's tie factor (above)
  uint8_t flags = 0;  // TriangleSetup::flags of `triangles`, or-ed (outputs.cpp: kExactDepth)
  // The sample this pass rasterizes, from each pixel's top-left corner (fixed point): the centre,
  // or one sample of a multisample pattern (viewport.hpp, multisample.cpp).
  int32_t sample_x = kSubpixelHalf, sample_y = kSubpixelHalf;

  // Before a tile of `rows` rows: nothing drawn. Only the rows the tile's kernels can touch are
  // written (its rows, the one past the last, and the lanes' spill), so a small frame (a 1x1
  // render, the bottom tiles of a 480-row image) does not clear a whole 64x64 tile.
  void clear(bool want_coverage, int rows);
};

// Rasterizes every triangle binned to `tile`, chunks in order, records in order: ties in depth
// keep the first triangle drawn, so the result is the same for any thread count.
// `kernel` (select_rasterize, once per render) is compiled for an instruction set (the same bits
// for either), whether coverage is counted and whether triangles are filled by scanline
// (RasterAlgorithm::Scanline).
using RasterizeFn = void (*)(const TileRect&, int, const std::vector<SetupChunk>&, std::size_t,
                             TileScratch&);
RasterizeFn select_rasterize(Isa isa, bool want_coverage, bool scanline);
void rasterize_tile(RasterizeFn kernel, const Viewport& viewport, int tile,
                    const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                    bool want_coverage, TileScratch& scratch);
// The same for every sample of a multisample pattern in one walk over the tile's records
// (multisample.cpp): each record is fetched once and rasterized into each sample's scratch
// (samples[s], at its own offset) in turn. Each scratch ends as rasterize_tile would leave it.
using RasterizeSamplesFn = void (*)(const TileRect&, int, const std::vector<SetupChunk>&,
                                    std::size_t, TileScratch* const*, int);
RasterizeSamplesFn select_rasterize_samples(Isa isa, bool want_coverage, bool scanline);

// Triangles whose snapped bounding box spans at most this many pixels per side take the
// eight-lane path: their edge functions, relative to a sample in the box, fit in int32.
constexpr int kSmallTrianglePx = 64;
inline bool is_small(const TriangleSetup& t) {
  const int32_t span_x = std::max({t.x[0], t.x[1], t.x[2]}) - std::min({t.x[0], t.x[1], t.x[2]});
  const int32_t span_y = std::max({t.y[0], t.y[1], t.y[2]}) - std::min({t.y[0], t.y[1], t.y[2]});
  return span_x <= kSmallTrianglePx * kSubpixelOne && span_y <= kSmallTrianglePx * kSubpixelOne;
}

// Unbiased edge functions E_k at the sample of pixel (x, y) at offset (sx, sy) from its corner
// (fixed point; the scratch's pass gives it), and their change per pixel step.
// Exact: |E| < 2^51 in general (see kGuardBandPx). For a small triangle and a pixel within its
// bounding box widened by a vector (kLanes - 1 pixels), |E| < 2^14 * (2^14 + 2^11) * 2 < 2^30,
// so values and steps fit in int32 and may be stepped there.
struct EdgeEquations {
  int64_t origin[3];
  int64_t step_x[3], step_y[3];
};
inline EdgeEquations edge_equations_at(const TriangleSetup& t, int x, int y, int32_t sample_x,
                                       int32_t sample_y) {
  EdgeEquations e;
  const int64_t px = int64_t(x) * kSubpixelOne + sample_x;
  const int64_t py = int64_t(y) * kSubpixelOne + sample_y;
  for (int k = 0; k < 3; ++k) {
    const int a = kEdgeStart[k], b = kEdgeEnd[k];
    const int64_t dx = t.x[b] - t.x[a], dy = t.y[b] - t.y[a];
    e.origin[k] = dx * (py - t.y[a]) - dy * (px - t.x[a]);
    e.step_x[k] = -dy * kSubpixelOne;
    e.step_y[k] = dx * kSubpixelOne;
  }
  return e;
}
// At the sample the scratch's pass rasterizes (TileScratch::sample_x / sample_y).
inline EdgeEquations edge_equations(const TriangleSetup& t, int x, int y, const TileScratch& s) {
  return edge_equations_at(t, x, y, s.sample_x, s.sample_y);
}

// A small triangle's edge functions for eight pixels of a row in exact int32 (see above), stepped
// eight pixels along a row (Cursor) and one row down (next_row); shared by raster and shading.
struct SmallEdges {
  simd::i8 row[3], step_x8[3], step_y[3];
  SR_INLINE explicit SmallEdges(const EdgeEquations& eq) {
    for (int k = 0; k < 3; ++k) {
      row[k] = simd::splat(int32_t(eq.origin[k])) + simd::lane_index() * int32_t(eq.step_x[k]);
      step_x8[k] = simd::splat(int32_t(eq.step_x[k] * simd::kLanes));
      step_y[k] = simd::splat(int32_t(eq.step_y[k]));
    }
  }
  struct Cursor {
    simd::i8 e[3];  // exact E_k at the eight pixels
    SR_INLINE simd::f8 edge(int k) const { return simd::to_float(e[k]); }
    SR_INLINE void next(const SmallEdges& s) { for (int k = 0; k < 3; ++k) e[k] += s.step_x8[k]; }
  };
  SR_INLINE Cursor cursor() const { return {{row[0], row[1], row[2]}}; }
  SR_INLINE void next_row() { for (int k = 0; k < 3; ++k) row[k] += step_y[k]; }
};

// The same for boxes at most four pixels wide: lanes 0-3 are pixels (x .. x + 3, y), lanes 4-7
// the pixels below them, so a tiny triangle takes half the iterations. The values are those of
// SmallEdges at the same pixels (the same exact integers).
struct SmallEdgePairs {
  simd::i8 e[3], step_y2[3];
  SR_INLINE explicit SmallEdgePairs(const EdgeEquations& eq) {
    const simd::i8 lane = simd::lane_index(), dx = lane & 3, dy = lane >> 2;
    for (int k = 0; k < 3; ++k) {
      e[k] = simd::splat(int32_t(eq.origin[k])) + dx * int32_t(eq.step_x[k]) +
             dy * int32_t(eq.step_y[k]);
      step_y2[k] = simd::splat(int32_t(eq.step_y[k] * 2));
    }
  }
  SR_INLINE simd::f8 edge(int k) const { return simd::to_float(e[k]); }
  SR_INLINE void next_rows() { for (int k = 0; k < 3; ++k) e[k] += step_y2[k]; }
};


// What the raster kernels do with the pixels a triangle wins in the depth test (its lanes `win`
// at scratch index i, with their exact edge values as floats). Deferred shading does nothing
// here: the tile's visibility buffer is shaded afterwards. Forward shading (shade.cpp) shades
// the lanes at once; triangles on the int64 path are left to a deferred pass (large_won).
struct NoShading {
  static constexpr bool kShades = false;
  SR_INLINE void triangle(const VisibleTriangle&) {}
  template <bool kPairs>
  SR_INLINE void shade(simd::i8, int, simd::f8, simd::f8, simd::f8) {}
  SR_INLINE void large_won(uint32_t) {}
  SR_INLINE void prefetch_attributes(const SetupChunk&, uint32_t) {}
};

// One pixel's depth test from its biased exact edge values e_k (all >= 0: covered): counts the
// fragment, and records the triangle if its key beats the pixel's. Shared by the int64 path and
// the scanline fill (scanline.cpp), so both compute the same float key from the same integers.
struct PixelDepthTest {
  float k0, k1, k2;
  int64_t b0, b1, b2;
  uint32_t index;
  SR_INLINE PixelDepthTest(const TriangleSetup& t, uint32_t i)
      : k0(t.key_over_area[0]), k1(t.key_over_area[1]), k2(t.key_over_area[2]),
        b0(t.bias[0]), b1(t.bias[1]), b2(t.bias[2]), index(i) {}
  SR_INLINE bool run(int i, int64_t e0, int64_t e1, int64_t e2, bool coverage,
                     TileScratch& s) const {
    if (coverage) ++s.coverage[i];
    // key = sum_k E_k * key_k / area2: barycentric weights from the exact edge values.
    const float key = float(e0 + b0) * k0 + float(e1 + b1) * k1 + float(e2 + b2) * k2;
    if (!(key > s.key[i] * s.tie)) return false;  // on a tie (kTieFactor*) the earlier one stays
    s.key[i] = key;
    s.visible[i] = index;
    return true;
  }
};

namespace raster {
using namespace simd;

// Any triangle, one pixel at a time, edge functions in int64.
template <bool kCoverage, typename Hook>
SR_INLINE void rasterize_large(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                               const TileRect& rect, uint32_t index, TileScratch& s, Hook& hook) {
  const EdgeEquations eq = edge_equations(t, x0, y0, s);
  int64_t row[3];
  for (int k = 0; k < 3; ++k) row[k] = eq.origin[k] - t.bias[k];  // biased: inside <=> >= 0
  const PixelDepthTest test(t, index);
  bool won = false;
  for (int y = y0; y <= y1; ++y) {
    int64_t e0 = row[0], e1 = row[1], e2 = row[2];
    const int line = (y - rect.y0) * kTileSizePx - rect.x0;
    for (int x = x0; x <= x1; ++x) {
      if ((e0 | e1 | e2) >= 0) won |= test.run(line + x, e0, e1, e2, kCoverage, s);
      e0 += eq.step_x[0]; e1 += eq.step_x[1]; e2 += eq.step_x[2];
    }
    row[0] += eq.step_y[0]; row[1] += eq.step_y[1]; row[2] += eq.step_y[2];
  }
  if (won) hook.large_won(index);
}

// A triangle's per-pixel constants in every lane: edge biases, depth-key weights, its index, the
// tie factor.
struct TriangleLanes {
  i8 bias[3];
  f8 key_k[3];
  i8 index;
  f8 tie;  // the render's tie factor (TileScratch::tie)
  SR_INLINE TriangleLanes(const TriangleSetup& t, uint32_t i, float tie_factor)
      : index(splat(int32_t(i))), tie(splat(tie_factor)) {
    for (int k = 0; k < 3; ++k) {
      bias[k] = splat(int32_t(t.bias[k]));
      key_k[k] = splat(t.key_over_area[k]);
    }
  }
};

// Eight lanes of a tile buffer at index i: a row of eight pixels, or (kPairs) four pixels of the
// row and the four below them.
template <bool kPairs, typename V, typename T>
SR_INLINE V load_lanes(const T* p) {
  if constexpr (kPairs) return load_pair<V>(p, kTileSizePx);
  else return load<V>(p);
}
template <bool kPairs, typename V, typename T>
SR_INLINE void store_lanes(T* p, V v) {
  if constexpr (kPairs) store_pair(p, kTileSizePx, v);
  else store(p, v);
}

// Counts, depth-tests and records the lanes `covered` (edge tests passed) of one triangle with
// exact edge values e (see lane layouts above), and hands the winners to the hook. The same
// float operations per pixel as rasterize_large, so the same bits.
template <bool kCoverage, bool kPairs, typename Hook>
SR_INLINE void depth_test(i8 covered, int i, f8 e0, f8 e1, f8 e2, const TriangleLanes& lanes,
                          TileScratch& s, Hook& hook) {
  if constexpr (kCoverage)
    store_lanes<kPairs>(s.coverage + i, load_lanes<kPairs, i8>(s.coverage + i) - covered);
  const f8 key = e0 * lanes.key_k[0] + e1 * lanes.key_k[1] + e2 * lanes.key_k[2];
  const f8 old = load_lanes<kPairs, f8>(s.key + i);
  const i8 win = covered & (key > old * lanes.tie);  // on a tie (kTieFactor*) the earlier one stays
  store_lanes<kPairs>(s.key + i, win ? key : old);
  store_lanes<kPairs>(s.visible + i, win ? lanes.index : load_lanes<kPairs, i8>(s.visible + i));
  if constexpr (Hook::kShades)
    if (any(win)) hook.template shade<kPairs>(win, i, e0, e1, e2);
}

// The edge tests of eight lanes: inside <=> E_k - bias_k >= 0 for every edge.
SR_INLINE i8 edges_cover(const i8 (&e)[3], const TriangleLanes& lanes) {
  return ((e[0] - lanes.bias[0]) | (e[1] - lanes.bias[1]) | (e[2] - lanes.bias[2])) >= 0;
}

// A small triangle (is_small), eight pixels of a row at a time in exact int32.
// (`lanes`: TriangleLanes(t, index, s.tie), made once for all of a pixel's samples.)
template <bool kCoverage, typename Hook>
SR_INLINE void rasterize_small(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                               const TileRect& rect, const TriangleLanes& lanes, TileScratch& s,
                               Hook& hook) {
  SmallEdges edges(edge_equations(t, x0, y0, s));
  const i8 lane = lane_index();
  const int width = x1 - x0 + 1;
  for (int y = y0; y <= y1; ++y, edges.next_row()) {
    int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    SmallEdges::Cursor c = edges.cursor();
    for (int dx = 0; dx < width; dx += kLanes, i += kLanes, c.next(edges)) {
      const i8 covered = edges_cover(c.e, lanes) & (lane < width - dx);
      if (any(covered))
        depth_test<kCoverage, false>(covered, i, c.edge(0), c.edge(1), c.edge(2), lanes, s, hook);
    }
  }
}

// A small triangle whose box (within the tile) is at most four pixels wide and more than one
// row high: two rows of four pixels at a time (SmallEdgePairs), otherwise as rasterize_small.
template <bool kCoverage, typename Hook>
SR_INLINE void rasterize_pairs(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                               const TileRect& rect, const TriangleLanes& lanes, TileScratch& s,
                               Hook& hook) {
  SmallEdgePairs edges(edge_equations(t, x0, y0, s));
  const i8 lane = lane_index(), row = lane >> 2;
  const i8 in_box_x = (lane & 3) < x1 - x0 + 1;
  for (int y = y0; y <= y1; y += 2, edges.next_rows()) {
    const int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
    const i8 covered = edges_cover(edges.e, lanes) & in_box_x & (row < y1 - y + 1);
    if (any(covered))
      depth_test<kCoverage, true>(covered, i, edges.edge(0), edges.edge(1), edges.edge(2), lanes,
                                  s, hook);
  }
}

// A tile's records are a sparse, ascending selection of its chunks' records: in a large mesh
// each is a cache miss, which hardware prefetchers do not foresee and which takes a large part
// of the tile pass. So the record this many places ahead is fetched early.
// Forward shading reads the record's TriangleShading too, where the triangle wins a pixel, and
// then its vertices' attributes, which are as scattered as the mesh's vertex order: the hook
// fetches those kPrefetchAttributes places ahead, from the TriangleShading fetched earlier
// (benchmarks/RESULTS.md, "Measurements behind the code").
constexpr uint32_t kPrefetchRecords = 16, kPrefetchAttributes = 8;
template <bool kShades>
SR_INLINE void prefetch_record(const SetupChunk& chunk, uint32_t r) {
  const uint32_t i = chunk.tile_records[r];
  __builtin_prefetch(chunk.records.data() + i);  // one cache line (SetupChunk)
  if constexpr (kShades) __builtin_prefetch(chunk.shading.data() + i);
}

// kScanline (render(raster="scanline"), deferred shading only: make_plan): every opaque
// triangle is filled by edge walking (scanline.hpp) instead of the kernels above.
template <bool kCoverage, bool kScanline = false, typename Hook>
SR_INLINE void rasterize_all(const TileRect& rect, int tile, const std::vector<SetupChunk>& chunks,
                             std::size_t num_chunks, TileScratch& s, Hook& hook) {
  for (std::size_t c = 0; c < num_chunks; ++c) {
    const SetupChunk& chunk = chunks[c];
    const uint32_t end = chunk.tile_begin[tile + 1];
    for (uint32_t r = chunk.tile_begin[tile]; r < end; ++r) {
      if (r + kPrefetchRecords < end) prefetch_record<Hook::kShades>(chunk, r + kPrefetchRecords);
      if (Hook::kShades && r + kPrefetchAttributes < end)
        hook.prefetch_attributes(chunk, chunk.tile_records[r + kPrefetchAttributes]);
      const TriangleSetup& t = chunk.records[chunk.tile_records[r]];
      const uint32_t index = uint32_t(s.triangles.size());
      // Field by field: an aggregate is built on the stack and copied with one wider load,
      // which cannot be forwarded from the two stores (a stall per triangle).
      VisibleTriangle& vt = s.triangles.emplace_back();
      vt.tri = &t;
      vt.chunk = &chunk;
      s.flags |= t.flags;
      hook.triangle(vt);
      const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
      const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
      if (x0 > x1 || y0 > y1) continue;
      if (chunk.alpha) {  // a masked draw's (alpha_mask.hpp): shaded as the int64 path's are
        if (rasterize_masked(*chunk.alpha, chunk, chunk.tile_records[r], x0, x1, y0, y1, rect,
                             index, s.sample_x, s.sample_y, kCoverage, s))
          hook.large_won(index);
        continue;
      }
      if constexpr (kScanline) {  // shaded as the int64 path's are (masked draws: above)
        if (rasterize_scanline(t, x0, x1, y0, y1, rect, index, s.sample_x, s.sample_y,
                               kCoverage, s))
          hook.large_won(index);
        continue;
      }
      if (is_small(t)) {
        const TriangleLanes lanes(t, index, s.tie);
        if (x1 - x0 < 4 && y1 > y0)
          rasterize_pairs<kCoverage>(t, x0, x1, y0, y1, rect, lanes, s, hook);
        else
          rasterize_small<kCoverage>(t, x0, x1, y0, y1, rect, lanes, s, hook);
      }
      else {
        rasterize_large<kCoverage>(t, x0, x1, y0, y1, rect, index, s, hook);
      }
    }
  }
}

// Walks a small triangle's box [x0, x1] x [y0, y1] (within the tile) eight lanes at a time, as
// rasterize_pairs (two rows of four pixels: kPairs) or rasterize_small (eight pixels of a row) do,
// calling group.run(e, i, in_box): the exact edge values of `eq` at the lanes' pixels, their scratch
// index and the lanes inside the box. (`group` is a struct with an SR_INLINE member, never a
// lambda: a lambda is not always inline, and out of line it is compiled for the generic target,
// not the kernel's, dispatch.hpp.)
template <bool kPairs, typename Group>
SR_INLINE void walk_small_box(const EdgeEquations& eq, int x0, int x1, int y0, int y1,
                              const TileRect& rect, Group& group) {
  const i8 lane = lane_index();
  if constexpr (kPairs) {
    SmallEdgePairs edges(eq);
    const i8 row = lane >> 2, in_box_x = (lane & 3) < x1 - x0 + 1;
    for (int y = y0; y <= y1; y += 2, edges.next_rows())
      group.run(edges.e, (y - rect.y0) * kTileSizePx + (x0 - rect.x0),
                in_box_x & (row < y1 - y + 1));
  } else {
    SmallEdges edges(eq);
    const int width = x1 - x0 + 1;
    for (int y = y0; y <= y1; ++y, edges.next_row()) {
      int i = (y - rect.y0) * kTileSizePx + (x0 - rect.x0);
      SmallEdges::Cursor c = edges.cursor();
      for (int dx = 0; dx < width; dx += kLanes, i += kLanes, c.next(edges))
        group.run(c.e, i, lane < width - dx);
    }
  }
}

// Several sample passes of a small triangle in one walk: the edge functions are affine, so pass
// s's exact values are the first pass's (`eq`) plus one constant per edge, E_s - E_0 =
// dx_k (sy_s - sy_0) - dy_k (sx_s - sx_0), all of them within int32 (|E| < 2^30, above): the same
// integers as a walk per pass. The constants for the pass of scratch `s`:
SR_INLINE void edge_offset(const TriangleSetup& t, int x0, int y0, const EdgeEquations& eq,
                           const TileScratch& s, int32_t (&offset)[3]) {
  const EdgeEquations es = edge_equations(t, x0, y0, s);
  for (int k = 0; k < 3; ++k) offset[k] = int32_t(es.origin[k] - eq.origin[k]);
}

// rasterize_small / rasterize_pairs for each sample's scratch, in one walk (walk_small_box).
template <bool kCoverage, bool kPairs>
struct SampleTests {
  const int32_t (*offset)[3];
  const TriangleLanes& lanes;
  TileScratch* const* samples;
  int count;
  SR_INLINE void run(const i8 (&e0)[3], int i, i8 in_box) {
    NoShading hook;
    for (int s = 0; s < count; ++s) {
      const i8 e[3] = {e0[0] + offset[s][0], e0[1] + offset[s][1], e0[2] + offset[s][2]};
      const i8 covered = edges_cover(e, lanes) & in_box;
      if (any(covered))
        depth_test<kCoverage, kPairs>(covered, i, to_float(e[0]), to_float(e[1]), to_float(e[2]),
                                      lanes, *samples[s], hook);
    }
  }
};

template <bool kCoverage, bool kPairs>
SR_INLINE void rasterize_small_samples(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                                       const TileRect& rect, const TriangleLanes& lanes,
                                       TileScratch* const* samples, int count) {
  const EdgeEquations eq = edge_equations(t, x0, y0, *samples[0]);
  int32_t offset[kMaxSamples][3];
  for (int s = 0; s < count; ++s) edge_offset(t, x0, y0, eq, *samples[s], offset[s]);
  SampleTests<kCoverage, kPairs> tests{offset, lanes, samples, count};
  walk_small_box<kPairs>(eq, x0, x1, y0, y1, rect, tests);
}

// rasterize_all for `count` samples at once (NoShading): samples[s] is rasterized at its own
// offset, with the same per-sample operations as rasterize_all, so the same bits.
template <bool kCoverage, bool kScanline>
SR_INLINE void rasterize_all_samples(const TileRect& rect, int tile,
                                     const std::vector<SetupChunk>& chunks, std::size_t num_chunks,
                                     TileScratch* const* samples, int count) {
  NoShading hook;
  for (std::size_t c = 0; c < num_chunks; ++c) {
    const SetupChunk& chunk = chunks[c];
    const uint32_t end = chunk.tile_begin[tile + 1];
    for (uint32_t r = chunk.tile_begin[tile]; r < end; ++r) {
      if (r + kPrefetchRecords < end) prefetch_record<false>(chunk, r + kPrefetchRecords);
      const TriangleSetup& t = chunk.records[chunk.tile_records[r]];
      const uint32_t index = uint32_t(samples[0]->triangles.size());
      for (int s = 0; s < count; ++s) {
        VisibleTriangle& vt = samples[s]->triangles.emplace_back();
        vt.tri = &t;
        vt.chunk = &chunk;
      }
      samples[0]->flags |= t.flags;  // (the write pass reads sample 0's list: multisample.cpp)
      const int x0 = std::max(int(t.x0), rect.x0), x1 = std::min(int(t.x1), rect.x1 - 1);
      const int y0 = std::max(int(t.y0), rect.y0), y1 = std::min(int(t.y1), rect.y1 - 1);
      if (x0 > x1 || y0 > y1) continue;
      if (chunk.alpha) {
        for (int s = 0; s < count; ++s)
          rasterize_masked(*chunk.alpha, chunk, chunk.tile_records[r], x0, x1, y0, y1, rect,
                           index, samples[s]->sample_x, samples[s]->sample_y, kCoverage,
                           *samples[s]);
        continue;
      }
      if constexpr (kScanline) {
        for (int s = 0; s < count; ++s)
          rasterize_scanline(t, x0, x1, y0, y1, rect, index, samples[s]->sample_x,
                             samples[s]->sample_y, kCoverage, *samples[s]);
        continue;
      }
      if (is_small(t)) {
        const TriangleLanes lanes(t, index, samples[0]->tie);  // (every pass has the render's)
        if (x1 - x0 < 4 && y1 > y0)
          rasterize_small_samples<kCoverage, true>(t, x0, x1, y0, y1, rect, lanes, samples, count);
        else
          rasterize_small_samples<kCoverage, false>(t, x0, x1, y0, y1, rect, lanes, samples, count);
      }
      else {
        for (int s = 0; s < count; ++s)
          rasterize_large<kCoverage>(t, x0, x1, y0, y1, rect, index, *samples[s], hook);
      }
    }
  }
}

}  // namespace raster
}  // namespace sr
