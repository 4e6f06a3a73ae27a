// Anti-aliasing: several samples per pixel (msaa, ssaa), each rasterized by its own pass over a
// tile, then resolved to one value per pixel.
//
// The raster kernels step one sample per pixel at the offset their scratch names
// (TileScratch::sample_x / sample_y), so a pattern of N samples is N passes of the same kernels
// into N scratch buffers: coverage, the top-left rule, watertightness and the depth test hold per
// sample exactly as for one sample, and every pass is the same bits for any thread count or
// instruction set. Setup and binning read the whole pattern (a triangle is kept if it may cover
// any sample).
//
// Resolve rules (the README states them):
//  - The representative sample of a pixel is its covered sample nearest the pixel centre, ties
//    to the lower sample index. Depth, mask, triangle_id, instance_id, normal and the surface
//    outputs (barycentric, uv, position, ray_depth) all come from it, so they describe one
//    surface point, and ids are never blended.
//  - alpha is the fraction of the pixel's samples covered.
//  - radiance is the mean over the samples of each one's shaded radiance, uncovered samples
//    counting 0 (premultiplied by alpha); the colour output encodes that plus (1 - alpha) times
//    the background's linear value, so a pixel mixes in linear light before it is encoded.
//  - msaa shades once per pixel per triangle: the samples a triangle wins in a pixel share one
//    shade, computed at the representative sample if the triangle owns it, else at the
//    triangle's lowest-index sample of the pixel (always a covered point: no extrapolation past
//    the triangle's edges), weighted by the number of samples. ssaa shades every sample.
//  - Blended draws (blend.hpp) composite per sample before the resolve, with either: each
//    sample's layers, shaded at that sample, over its opaque surface.
#pragma once

#include "shade.hpp"

#include <memory>
#include <vector>

namespace sr {

struct PrimitiveSetup;   // lines.hpp
struct PrimitivePixels;
struct BlendParams;      // blend.hpp
struct BlendScratch;

// The most samples msaa_pattern makes: the resolve of a render shading once per pixel per
// triangle keeps that many weights per lane group (multisample_tile requires it).
constexpr int kMaxMsaaSamples = 16;

// The Direct3D / Vulkan standard sample positions for msaa = 1, 2, 4, 8, 16 (offsets from the
// pixel's top-left corner, fixed point); throws std::invalid_argument for another count.
SamplePattern msaa_pattern(int count);
// A k x k grid at ((i + 1/2) / k, (j + 1/2) / k) of the pixel, each offset rounded to the
// nearest 1/256 px (exact for k = 1, 2, 4, 8), row by row; k in [1, 8].
SamplePattern ssaa_pattern(int k);

// What write_tile needs beyond a single-sample tile: per pixel, the representative sample, alpha,
// the radiance (premultiplied) and the coverage summed over the samples.
struct ResolvedSamples {
  const int32_t* representative;  // sample index per tile pixel (row stride kTileSizePx)
  const SamplePattern* pattern;
  const float* alpha;             // per tile pixel
  const float* radiance[3];       // per tile pixel, premultiplied
  const uint32_t* coverage;       // fragments over all samples
};

// Sample passes shaded together: each visible triangle is prepared once per batch for all the
// passes of it that it owns pixels in (most triangles of a detailed mesh own pixels in several:
// their edges cross most pixels), at the cost of a shade scratch per pass of the batch.
constexpr int kShadeBatch = kMaxShadePasses;

// Per-thread scratch of the multisample tile pass, allocated on a worker's first multisample
// tile (renders without anti-aliasing never allocate it).
struct MultisampleScratch {
  std::vector<std::unique_ptr<TileScratch>> sample;  // one per sample of the pattern
  TileScratch resolved;  // the representative sample's key and visible entry per pixel
  ShadeScratch shaded[kShadeBatch];  // the shade of each pass of a batch
  ShadeScratch resolved_shade;  // rgb: the colour output's linear value; normal: the
                                // representative's
  float radiance[3][kTileScratchPixels];
  float alpha[kTileScratchPixels];
  uint32_t coverage[kTileScratchPixels];
  int32_t representative[kTileScratchPixels];
  int32_t weight[kMaxSamples][kTilePixels];  // samples one pass's shade stands for (0: none)
  float blend_alpha[kTileScratchPixels];      // blending: alpha summed over samples
  // msaa with blending: the blended layers' premultiplied radiance summed over samples (times
  // kSumScale), and per pass first each sample's transmittance, then the weight of the pass's
  // shade: the transmittances of the samples it stands for, summed.
  float blend_sum[3][kTileScratchPixels];
  float blend_weight[kMaxMsaaSamples][kTilePixels];
};

// Rasterizes, shades and resolves `tile` with the viewport's sample pattern (count > 1), then
// writes it. `per_sample`: shade every sample (ssaa) rather than once per pixel per triangle.
// `tie` is the render's tie factor (rasterize.hpp); `background_linear` the background colour's
// linear value, mixed into partly covered pixels of the colour output. `primitives` (or null):
// the render's lines and points, drawn over the resolved tile (whole pixels, alpha 1) with
// `pixels` as their scratch. `blend` (with `blend_scratch`): the render's blended draws,
// composited at every sample over that sample's opaque surface before the resolve (blend.hpp):
// radiance and colour are the mean of the samples' composites, alpha the mean of their coverage
// (1 - transmittance where no opaque surface is seen). Blended layers are shaded at each sample
// they cover, with msaa too; msaa's opaque shade, shared by a triangle's samples in a pixel, is
// weighted by the transmittance in front of each of those samples.
void multisample_tile(const ShadeParams& params, const TileKernels& kernels,
                      const Viewport& viewport, int tile, const std::vector<SetupChunk>& chunks,
                      std::size_t num_chunks, bool per_sample, float tie,
                      const vec3& background_linear, MultisampleScratch& scratch,
                      const PrimitiveSetup* primitives = nullptr,
                      PrimitivePixels* pixels = nullptr, const BlendParams* blend = nullptr,
                      BlendScratch* blend_scratch = nullptr);

}  // namespace sr
