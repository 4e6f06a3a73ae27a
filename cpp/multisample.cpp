// Anti-aliasing: one raster pass per sample, then the resolve (multisample.hpp states the rules).
// Scalar and compiled once for the generic target: its sums are the same bits for either
// instruction set's kernels.
#include "multisample.hpp"

#include "outputs.hpp"

#include <algorithm>
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
      throw std::invalid_argument("msaa must be 1, 2, 4, 8 or 16, got " + std::to_string(count));
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

void multisample_tile(const ShadeParams& params, const TileKernels& kernels,
                      const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                      std::size_t num_chunks, bool per_sample, float tie,
                      const vec3& background_linear, MultisampleScratch& ms) {
  const SamplePattern& pattern = viewport.samples;
  const int count = pattern.count;
  const TileRect rect = tile_rect(viewport, tile);
  const int w = rect.x1 - rect.x0, h = rect.y1 - rect.y0;

  // One raster pass per sample.
  while (int(ms.sample.size()) < count) ms.sample.emplace_back(new TileScratch);
  for (int s = 0; s < count; ++s) {
    TileScratch& scratch = *ms.sample[s];
    scratch.tie = tie;
    scratch.sample_x = pattern.x[s];
    scratch.sample_y = pattern.y[s];
    rasterize_tile(kernels.raster, viewport, tile, chunks, num_chunks, kernels.coverage, scratch);
  }

  // Per pixel: the representative sample, alpha, coverage, and which pass shades which samples.
  uint8_t order[kMaxSamples];
  representative_order(pattern, order);
  const float inv_count = 1.0f / float(count);
  constexpr uint8_t kNone = 0xff;
  TileScratch& resolved = ms.resolved;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int i = y * kTileSizePx + x;
      int rep = kNone, covered = 0;
      for (int r = 0; r < count; ++r)
        if (ms.sample[order[r]]->visible[i] != kNoTriangle) {
          rep = order[r];
          break;
        }
      for (int s = 0; s < count; ++s) {
        ms.weight[s][i] = 0;
        covered += ms.sample[s]->visible[i] != kNoTriangle;
      }
      ms.representative[i] = uint8_t(rep);
      ms.alpha[i] = float(covered) * inv_count;
      if (kernels.coverage) {
        uint32_t fragments = 0;
        for (int s = 0; s < count; ++s) fragments += ms.sample[s]->coverage[i];
        ms.coverage[i] = fragments;
      }
      if (rep == kNone) {
        resolved.visible[i] = kNoTriangle;
        resolved.key[i] = -std::numeric_limits<float>::infinity();
        continue;
      }
      const uint32_t owner = ms.sample[rep]->visible[i];
      resolved.visible[i] = owner;
      resolved.key[i] = ms.sample[rep]->key[i];
      if (per_sample) {
        for (int s = 0; s < count; ++s) ms.weight[s][i] = ms.sample[s]->visible[i] != kNoTriangle;
        continue;
      }
      // Once per pixel per triangle: the representative shades its triangle's samples; another
      // triangle's samples are shaded by its lowest-index sample.
      for (int s = 0; s < count; ++s) {
        const uint32_t v = ms.sample[s]->visible[i];
        if (v == kNoTriangle) continue;
        int leader = rep;
        if (v != owner)
          for (leader = 0; ms.sample[leader]->visible[i] != v; ++leader) {}
        ++ms.weight[leader][i];
      }
    }

  // Shading: pass s shades the pixels where its weight is set (the others are masked off in its
  // visibility buffer, which the resolve no longer reads), and its shade is summed with that
  // weight. The representative's pass also gives the pixel its normal.
  if (kernels.deferred) {
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < h; ++y) std::fill_n(ms.radiance[c] + y * kTileSizePx, w, 0.0f);
    for (int s = 0; s < count; ++s) {
      TileScratch& scratch = *ms.sample[s];
      bool any = false;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const int i = y * kTileSizePx + x;
          if (ms.weight[s][i] == 0) scratch.visible[i] = kNoTriangle;
          else any = true;
        }
      if (!any) continue;
      kernels.deferred(params, rect, scratch, ms.shaded);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const int i = y * kTileSizePx + x;
          const uint8_t weight = ms.weight[s][i];
          if (weight == 0) continue;
          for (int c = 0; c < 3; ++c) ms.radiance[c][i] += float(weight) * ms.shaded.rgb[c][i];
          if (ms.representative[i] == s)
            for (int c = 0; c < 3; ++c) ms.resolved_shade.normal[c][i] = ms.shaded.normal[c][i];
        }
    }
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const int i = y * kTileSizePx + x;
        const float background = 1.0f - ms.alpha[i];
        for (int c = 0; c < 3; ++c) {
          const float mean = ms.radiance[c][i] * inv_count;
          ms.radiance[c][i] = mean;
          ms.resolved_shade.rgb[c][i] = mean + background * background_linear[c];
        }
      }
  }

  // The write pass reads the resolved buffer's entries as indices into the (shared) list of the
  // tile's triangles, which every pass built alike: take sample 0's.
  std::swap(resolved.triangles, ms.sample[0]->triangles);
  const ResolvedSamples samples{ms.representative, &pattern, ms.alpha,
                                {ms.radiance[0], ms.radiance[1], ms.radiance[2]},
                                ms.coverage};
  write_tile(params, rect, resolved, ms.resolved_shade, kernels.isa, &samples);
}

}  // namespace sr
