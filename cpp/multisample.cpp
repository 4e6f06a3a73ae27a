// Anti-aliasing: one raster pass per sample, then the resolve (multisample.hpp states the rules).
#include "multisample.hpp"

#include "blend.hpp"
#include "dispatch.hpp"
#include "lines.hpp"
#include "outputs.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

namespace sr {

namespace {

// Offsets in 1/16 px from the pixel centre (Direct3D 11's standard patterns, which Vulkan's
// standardSampleLocations and Metal repeat), y down as in window coordinates.
constexpr int8_t kMsaa2[2][2] = {{4, 4}, {-4, -4}};
constexpr int8_t kMsaa4[4][2] = {{-2, -6}, {6, -2}, {-6, 2}, {2, 6}};
constexpr int8_t kMsaa8[8][2] = {{1, -3}, {-1, 3}, {5, 1}, {-3, -5},
                                 {-5, 5}, {-7, -1}, {3, 7}, {7, -7}};
constexpr int8_t kMsaa16[16][2] = {{1, 1},   {-1, -3}, {-3, 2}, {4, -1}, {-5, -2}, {2, 5},
                                   {5, 3},   {3, -5},  {-2, 6}, {0, -7}, {-4, -6}, {-6, 4},
                                   {-8, 0},  {7, -4},  {6, 7},  {-7, -8}};

template <int N>
SamplePattern from_sixteenths(const int8_t (&offsets)[N][2]) {
  int32_t xs[N], ys[N];
  for (int i = 0; i < N; ++i) {
    xs[i] = kSubpixelHalf + offsets[i][0] * (kSubpixelOne / 16);
    ys[i] = kSubpixelHalf + offsets[i][1] * (kSubpixelOne / 16);
  }
  return SamplePattern::of(N, xs, ys);
}

// Sample indices nearest the pixel centre first, ties to the lower index.
void representative_order(const SamplePattern& pattern, uint8_t* order) {
  for (int s = 0; s < pattern.count; ++s) order[s] = uint8_t(s);
  auto dist2 = [&](int s) {
    const int64_t dx = pattern.x[s] - kSubpixelHalf, dy = pattern.y[s] - kSubpixelHalf;
    return dx * dx + dy * dy;
  };
  std::stable_sort(order, order + pattern.count,
                   [&](uint8_t a, uint8_t b) { return dist2(a) < dist2(b); });
}

}  // namespace

SamplePattern msaa_pattern(int count) {
  switch (count) {
    case 1: return SamplePattern::centre();
    case 2: return from_sixteenths(kMsaa2);
    case 4: return from_sixteenths(kMsaa4);
    case 8: return from_sixteenths(kMsaa8);
    case 16: return from_sixteenths(kMsaa16);
    default:
      throw std::invalid_argument("msaa must be one of (1, 2, 4, 8, 16), got " + std::to_string(count));
  }
}

SamplePattern ssaa_pattern(int k) {
  if (k < 1 || k > 8) throw std::invalid_argument("ssaa must be in [1, 8], got " + std::to_string(k));
  int32_t xs[kMaxSamples], ys[kMaxSamples];
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) {
      // (2i + 1) / (2k) of a pixel, rounded to the nearest fixed-point unit.
      xs[j * k + i] = int32_t(((2 * i + 1) * kSubpixelOne + k) / (2 * k));
      ys[j * k + i] = int32_t(((2 * j + 1) * kSubpixelOne + k) / (2 * k));
    }
  return SamplePattern::of(k * k, xs, ys);
}

namespace {

using namespace simd;

// The per-pixel work of multisample_tile, eight lanes at a time over whole tile rows (columns
// past the tile's width hold kNoTriangle in every sample's buffer: their results are never
// read), compiled for each instruction set (IsaKernel): selects, integer counts and IEEE single
// adds and products, the same bits for either.
struct Resolve {
  // The representative sample, its entries, alpha and coverage; weights when shading.
  SR_INLINE static void run(MultisampleScratch* ms_, int n, int count, const uint8_t* order,
                            bool coverage, bool shading, bool per_sample) {
    MultisampleScratch& ms = *ms_;
    const float inv_count = 1.0f / float(count);
    const i8 none = splat(int32_t(kNoTriangle));
    // Each sample's index in every lane, made by adds (a broadcast per use became a chain of
    // lane inserts).
    i8 ids[kMaxSamples];
    i8 id = splat(0);
    for (int s = 0; s < count; ++s, id += 1) ids[s] = id;
    for (int i = 0; i < n; i += kLanes) {
      i8 visible = none, rep = splat(0), covered = splat(0);
      f8 key = splat(-std::numeric_limits<float>::infinity());
      for (int r = count - 1; r >= 0; --r) {  // the most preferred last: it wins
        const int s = order[r];
        const i8 v = load<i8>(ms.sample[s]->visible + i);
        const i8 hit = v != none;
        visible = hit ? v : visible;
        key = hit ? load<f8>(ms.sample[s]->key + i) : key;
        rep = hit ? ids[s] : rep;
        covered -= hit;
      }
      store(ms.resolved.visible + i, visible);
      store(ms.resolved.key + i, key);
      store(ms.representative + i, rep);
      store(ms.alpha + i, to_float(covered) * inv_count);  // (an integer times 1/count)
      if (coverage) {
        i8 fragments = splat(0);
        for (int s = 0; s < count; ++s) fragments += load<i8>(ms.sample[s]->coverage + i);
        store(ms.coverage + i, fragments);
      }
      if (!shading) continue;
      // Which pass shades which samples. ssaa: every covered sample its own. msaa: the
      // representative shades its triangle's samples; another triangle's are shaded by its
      // lowest-index sample (its leader), found only where several triangles show.
      if (per_sample) {
        for (int s = 0; s < count; ++s)
          store(ms.weight[s] + i, (load<i8>(ms.sample[s]->visible + i) != none) & splat(1));
        continue;
      }
      i8 mine = splat(0);
      for (int s = 0; s < count; ++s) {
        const i8 v = load<i8>(ms.sample[s]->visible + i);
        mine -= (v == visible) & (v != none);
      }
      // Each sample of another triangle adds one to its leader's weight (msaa: at most 16
      // samples, count^2 / 2 compares per group).
      i8 weight[kMaxMsaaSamples];
      for (int s = 0; s < count; ++s) weight[s] = rep == ids[s] ? mine : i8{};
      if (any(mine != covered)) {
        for (int s = 0; s < count; ++s) {
          const i8 v = load<i8>(ms.sample[s]->visible + i);
          const i8 other = (v != none) & (v != visible);  // all ones where counted
          if (!any(other)) continue;
          i8 leader = ids[s];
          for (int t = s - 1; t >= 0; --t)
            leader = load<i8>(ms.sample[t]->visible + i) == v ? ids[t] : leader;
          for (int t = 0; t <= s; ++t) weight[t] -= (leader == ids[t]) & other;
        }
      }
      for (int s = 0; s < count; ++s) store(ms.weight[s] + i, weight[s]);
    }
  }
};

// Pass s's visibility buffer keeps only the pixels it shades; true if there is one.
struct MaskPass {
  SR_INLINE static bool run(MultisampleScratch* ms, int n, int s) {
    const i8 none = splat(int32_t(kNoTriangle));
    i8 any_weight = splat(0);
    uint32_t* const visible = ms->sample[s]->visible;
    for (int i = 0; i < n; i += kLanes) {
      const i8 weight = load<i8>(ms->weight[s] + i);
      store(visible + i, weight != 0 ? load<i8>(visible + i) : none);
      any_weight |= weight;
    }
    return any(any_weight != 0);
  }
};

// Adds pass s's shade (`shaded`) times its weights; the representative's pass gives the normal.
// Samples are summed scaled by kSumScale (Accumulate) and the mean scaled back (Finish).
constexpr float kSumScale = 1.0f / 128.0f;
static_assert(kMaxSamples <= 128, "the scaled sum of kMaxSamples finite samples stays finite");

struct Accumulate {
  SR_INLINE static void run(MultisampleScratch* ms, const ShadeScratch* shaded, int n, int s,
                            bool normals) {
    const i8 me = splat(s);
    for (int i = 0; i < n; i += kLanes) {
      const i8 weight = load<i8>(ms->weight[s] + i);
      if (!any(weight != 0)) continue;
      // The weight times 2^-7: a sum of up to 64 samples of the largest finite radiance stays
      // finite (Finish scales back). A power of two scales exactly: the same bits as the plain
      // sum, but for radiance below ~1e-36.
      const f8 w = to_float(weight) * kSumScale;
      // (selects, not products alone: a pixel this pass did not shade holds a stale value)
      for (int c = 0; c < 3; ++c)
        store(ms->radiance[c] + i, load<f8>(ms->radiance[c] + i) +
                                       (weight != 0 ? w * load<f8>(shaded->rgb[c] + i) : f8{}));
      if (normals) {
        const i8 mine = (weight != 0) & (load<i8>(ms->representative + i) == me);
        for (int c = 0; c < 3; ++c)
          store(ms->resolved_shade.normal[c] + i,
                mine ? load<f8>(shaded->normal[c] + i) : load<f8>(ms->resolved_shade.normal[c] + i));
      }
    }
  }
};

// The mean, and the colour output's value: the mean plus the background's uncovered share.
struct Finish {
  SR_INLINE static void run(MultisampleScratch* ms, int n, int count, const float* background) {
    const f8 inv = splat(1.0f / float(count) / kSumScale), one = splat(1.0f);
    const f8 bg[3] = {splat(background[0]), splat(background[1]), splat(background[2])};
    for (int i = 0; i < n; i += kLanes) {
      const f8 uncovered = one - load<f8>(ms->alpha + i);
      for (int c = 0; c < 3; ++c) {
        const f8 mean = load<f8>(ms->radiance[c] + i) * inv;
        store(ms->radiance[c] + i, mean);
        store(ms->resolved_shade.rgb[c] + i, mean + uncovered * bg[c]);
      }
    }
  }
};

template <typename K, typename Fn>
Fn kernel(Isa isa) {
  return dispatch::IsaKernel<K, Fn>::get(isa);
}

// ssaa with blended draws: composites sample s's blended fragments over its opaque surface
// (`raster`, and its shade `shaded` when colour is shaded), adds the sample's alpha to
// ms.blend_alpha, and leaves the composite (premultiplied) in shaded.rgb with the sample's weight
// set wherever something is seen there, for Accumulate. Scalar, compiled once.
// blend_tile at one sample (its raster `raster`, of rank `rank` in the representative order): the
// layers walked and shaded at the sample's position, and with an alpha threshold the sample's
// fragments reaching it kept (blend_surface_sample).
bool blend_at_sample(const BlendParams& blend, const TileRect& rect, int tile,
                     const TileScratch& raster, const ShadeScratch& shade, int rank, BlendScratch& bs) {
  for (TileScratch& layer : bs.layer) {
    layer.sample_x = raster.sample_x;
    layer.sample_y = raster.sample_y;
    layer.tie = raster.tie;
  }
  const bool composited = blend_tile(blend, rect, tile, raster, shade, bs);
  if (composited && blend.surfaces) blend_surface_sample(blend, rect, rank, bs);
  return composited;
}

void blend_sample(const BlendParams& blend, const TileRect& rect, int tile, const TileScratch& raster,
                  ShadeScratch* shaded, BlendScratch& bs, MultisampleScratch& ms, int s, int rank,
                  int n) {
  // (shaded null: alpha alone; blend_tile then reads no shade)
  const bool composited =
      blend_at_sample(blend, rect, tile, raster, shaded ? *shaded : ms.resolved_shade, rank, bs);
  const int width = rect.x1 - rect.x0;
  for (int row = 0; row < n; row += kTileSizePx)
    for (int i = row; i < row + width; ++i) {
      if (!composited) {
        ms.blend_alpha[i] += raster.visible[i] != kNoTriangle ? 1.0f : 0.0f;
        continue;
      }
      ms.blend_alpha[i] += bs.alpha[i];
      if (shaded && bs.seen[i] != kNoTriangle) {
        for (int c = 0; c < 3; ++c) shaded->rgb[c][i] = bs.radiance[c][i];
        ms.weight[s][i] = 1;
      }
    }
}

// msaa with blended draws, before the shading passes mask their visibility buffers: composites
// every sample's blended layers (shaded at the sample) in front of its opaque surface, adding
// their premultiplied radiance to ms.blend_sum (times kSumScale) and the sample's alpha to
// ms.blend_alpha; then sets ms.blend_weight[p] of each pass p that shades a pixel (weight[p] set)
// to the transmittances in front of the samples its shade stands for (its triangle's), summed:
// the opaque shade's share of the mean. False (with blend_alpha still summed) where no sample of
// the tile has a blended fragment in front: the plain weights hold. Scalar, compiled once.
bool msaa_blend(const BlendParams& blend, const TileRect& rect, int tile, TileScratch* const* passes,
                int count, const uint8_t* rank_of, BlendScratch& bs, MultisampleScratch& ms, int n) {
  const int width = rect.x1 - rect.x0;
  bool any = false;
  for (int s = 0; s < count; ++s) {
    const TileScratch& raster = *passes[s];
    // (The composite's own colour planes are not read: the opaque shade is not known yet, so
    // any shade stands in for it.)
    const bool composited = blend_at_sample(blend, rect, tile, raster, ms.resolved_shade, rank_of[s], bs);
    any |= composited;
    const TileRect& box = bs.box;
    float* const transmit = ms.blend_weight[s];
    for (int row = 0; row < n; row += kTileSizePx)
      for (int i = row; i < row + width; ++i) {
        const int x = rect.x0 + (i - row), y = rect.y0 + row / kTileSizePx;
        const bool layers = composited && x >= box.x0 && x < box.x1 && y >= box.y0 &&
                            y < box.y1 && bs.touched[i];
        const float t = layers ? bs.transmit[i] : 1.0f;
        transmit[i] = t;
        ms.blend_alpha[i] += raster.visible[i] != kNoTriangle ? 1.0f : 1.0f - t;
        if (layers)
          for (int c = 0; c < 3; ++c) ms.blend_sum[c][i] += kSumScale * bs.sum[c][i];
      }
  }
  if (!any) return false;
  for (int row = 0; row < n; row += kTileSizePx)
    for (int i = row; i < row + width; ++i) {
      uint32_t visible[kMaxMsaaSamples];
      float t[kMaxMsaaSamples];
      for (int s = 0; s < count; ++s) {
        visible[s] = passes[s]->visible[i];
        t[s] = ms.blend_weight[s][i];
      }
      for (int p = 0; p < count; ++p) {
        float w = 0.0f;
        if (ms.weight[p][i] != 0)
          for (int s = 0; s < count; ++s) w += visible[s] == visible[p] ? t[s] : 0.0f;
        ms.blend_weight[p][i] = w;
      }
    }
  return true;
}

// Accumulate with msaa_blend's weights (scalar): pass s's shade times its blend_weight. Where
// every transmittance is 1 the weight is the sample count, and the sum the same bits as
// Accumulate's.
void accumulate_blended(MultisampleScratch& ms, const ShadeScratch& shaded, const TileRect& rect,
                        int n, int s, bool normals) {
  const int width = rect.x1 - rect.x0;
  for (int row = 0; row < n; row += kTileSizePx)
    for (int i = row; i < row + width; ++i) {
      if (ms.weight[s][i] == 0) continue;
      const float w = ms.blend_weight[s][i] * kSumScale;
      for (int c = 0; c < 3; ++c) ms.radiance[c][i] += w * shaded.rgb[c][i];
      if (normals && ms.representative[i] == s)
        for (int c = 0; c < 3; ++c) ms.resolved_shade.normal[c][i] = shaded.normal[c][i];
    }
}

}  // namespace

void multisample_tile(const ShadeParams& params, const TileKernels& kernels,
                      const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                      std::size_t num_chunks, bool per_sample, float tie,
                      const vec3& background_linear, MultisampleScratch& ms,
                      const PrimitiveSetup* primitives, PrimitivePixels* pixels,
                      const BlendParams* blend, BlendScratch* blend_scratch) {
  const SamplePattern& pattern = viewport.samples;
  const int count = pattern.count;
  const TileRect rect = tile_rect(viewport, tile);
  const int n = (rect.y1 - rect.y0) * kTileSizePx;  // whole rows of the tile's buffers
  const Isa isa = kernels.isa;

  // Every sample's raster pass, in one walk over the tile's triangles.
  while (int(ms.sample.size()) < count) ms.sample.emplace_back(new TileScratch);
  TileScratch* passes[kMaxSamples];
  for (int s = 0; s < count; ++s) {
    passes[s] = ms.sample[s].get();
    passes[s]->tie = tie;
    passes[s]->sample_x = pattern.x[s];
    passes[s]->sample_y = pattern.y[s];
  }
  kernels.raster_samples(rect, tile, chunks, num_chunks, passes, count);

  uint8_t order[kMaxSamples], rank_of[kMaxSamples];
  representative_order(pattern, order);
  for (int r = 0; r < count; ++r) rank_of[order[r]] = uint8_t(r);
  const bool shading = kernels.deferred != nullptr;
  kernel<Resolve, void (*)(MultisampleScratch*, int, int, const uint8_t*, bool, bool, bool)>(isa)(
      &ms, n, count, order, kernels.coverage, shading, per_sample);

  // Blended draws: every sample composited before the resolve (ssaa: blend_sample, after each
  // pass is shaded; msaa: msaa_blend, here, while every pass's visibility is whole).
  const bool blending = blend && blend_scratch;
  // (Layers shaded for the normal output alone, with an alpha threshold, composite no colour.)
  const bool blend_colour = blending && blend->shade && blend->shade->color;
  if (blending) std::fill_n(ms.blend_alpha, n, 0.0f);
  if (blending && blend->surfaces) clear_blend_surfaces(rect, *blend_scratch);
  // Shading: pass s shades the pixels where its weight is set (the others are masked off in its
  // visibility buffer, which the resolve no longer reads), and its shade is summed with that
  // weight.
  if (blending && !blend_colour) {  // (alpha alone: no colour is shaded)
    for (int s = 0; s < count; ++s)
      blend_sample(*blend, rect, tile, *passes[s], nullptr, *blend_scratch, ms, s, rank_of[s], n);
  }
  bool msaa_layers = false;  // msaa: some sample has a blended fragment in front
  if (blend_colour && !per_sample) {
    for (int c = 0; c < 3; ++c) std::fill_n(ms.blend_sum[c], n, 0.0f);
    msaa_layers = msaa_blend(*blend, rect, tile, passes, count, rank_of, *blend_scratch, ms, n);
  }
  if (blending && (!blend_colour || !per_sample)) {
    const float inv = 1.0f / float(count);
    for (int i = 0; i < n; ++i) ms.alpha[i] = ms.blend_alpha[i] * inv;
  }
  if (shading) {
    const bool normals = params.framebuffer->get<float>(kOutNormal) != nullptr;
    for (int c = 0; c < 3; ++c) std::fill_n(ms.radiance[c], n, 0.0f);
    const auto mask = kernel<MaskPass, bool (*)(MultisampleScratch*, int, int)>(isa);
    const auto accumulate =
        kernel<Accumulate, void (*)(MultisampleScratch*, const ShadeScratch*, int, int, bool)>(isa);
    for (int first = 0; first < count; first += kShadeBatch) {
      // The batch's passes that shade a pixel, each with its own scratch.
      const TileScratch* rasters[kShadeBatch];
      ShadeScratch* outs[kShadeBatch];
      int pass[kShadeBatch], m = 0;
      for (int s = first; s < std::min(count, first + kShadeBatch); ++s) {
        if (!mask(&ms, n, s) && !(blend_colour && per_sample)) continue;
        rasters[m] = ms.sample[s].get();
        outs[m] = &ms.shaded[m];
        pass[m++] = s;
      }
      if (m == 0) continue;
      kernels.deferred(params, rect, rasters, outs, m);
      for (int k = 0; k < m; ++k) {
        if (msaa_layers) {
          accumulate_blended(ms, *outs[k], rect, n, pass[k], normals);
          continue;
        }
        if (blend_colour)
          blend_sample(*blend, rect, tile, *rasters[k], outs[k], *blend_scratch, ms, pass[k],
                       rank_of[pass[k]], n);
        accumulate(&ms, outs[k], n, pass[k], normals);
      }
    }
    if (msaa_layers)  // (the layers' share of the mean)
      for (int c = 0; c < 3; ++c)
        for (int i = 0; i < n; ++i) ms.radiance[c][i] += ms.blend_sum[c][i];
    if (blend_colour && per_sample) {  // (alpha: the mean of the samples' coverage, layers included)
      const float inv = 1.0f / float(count);
      for (int i = 0; i < n; ++i) ms.alpha[i] = ms.blend_alpha[i] * inv;
    }
    const float background[3] = {background_linear.x, background_linear.y, background_linear.z};
    kernel<Finish, void (*)(MultisampleScratch*, int, int, const float*)>(isa)(&ms, n, count,
                                                                                background);
  }

  // The write pass reads the resolved buffer's entries as indices into the (shared) list of the
  // tile's triangles, which every pass built alike: take sample 0's.
  std::swap(ms.resolved.triangles, ms.sample[0]->triangles);
  ms.resolved.flags = ms.sample[0]->flags;
  // With an alpha threshold: blended fragments reaching it stand for the surface (blend.hpp).
  if (blending && blend->surfaces) {
    float* const normal[3] = {ms.resolved_shade.normal[0], ms.resolved_shade.normal[1],
                              ms.resolved_shade.normal[2]};
    take_blend_surfaces_multisample(*blend, rect, *blend_scratch, order, rank_of, ms.resolved,
                                    ms.representative, normal);
  }
  const ResolvedSamples samples{ms.representative, &pattern, ms.alpha,
                                {ms.radiance[0], ms.radiance[1], ms.radiance[2]},
                                ms.coverage};
  // Lines and points over the resolved pixels: aliased, whole pixels of alpha 1 (lines.hpp).
  const bool overlay = primitives && primitives->any(tile);
  if (overlay) {
    ShadeScratch& shade = ms.resolved_shade;
    const OverlayTarget target{ms.resolved.key, ms.resolved.visible,
                               {shade.rgb[0], shade.rgb[1], shade.rgb[2]},
                               {shade.normal[0], shade.normal[1], shade.normal[2]},
                               ms.alpha, {ms.radiance[0], ms.radiance[1], ms.radiance[2]},
                               tie, pixels};
    draw_primitives_tile(*primitives, rect, tile, target);
  }
  // With blended layers a pixel shows something where any sample saw an opaque surface or a
  // layer: write_tile takes colour and radiance from the composite's planes (blend.hpp's), here
  // the resolved means.
  BlendScratch* composited = nullptr;
  if (blend_colour) {
    composited = blend_scratch;
    const int width = rect.x1 - rect.x0;
    for (int row = 0; row < n; row += kTileSizePx)
      for (int i = row; i < row + width; ++i) {
        const bool seen = ms.resolved.visible[i] != kNoTriangle || ms.alpha[i] > 0.0f;
        composited->seen[i] = seen ? 0u : kNoTriangle;
        composited->alpha[i] = ms.alpha[i];
        for (int c = 0; c < 3; ++c) {
          composited->color[c][i] = ms.resolved_shade.rgb[c][i];
          composited->radiance[c][i] = ms.radiance[c][i];
        }
      }
  }
  write_tile(params, rect, ms.resolved, ms.resolved_shade, isa, &samples,
             overlay ? pixels : nullptr, composited);
}

}  // namespace sr
