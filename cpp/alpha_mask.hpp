// Alpha masks (glTF alphaMode MASK): a masked draw's fragments are kept only where its alpha
// reaches the cutoff, before the depth test, so whatever lies behind a cut-out shows through.
// Its triangles take this scalar raster path (alpha_mask.cpp, compiled once for the generic
// target: the same bits under either instruction set's kernels); other draws never branch on
// it more than once per triangle (SetupChunk::alpha).
#pragma once

#include "pipeline.hpp"
#include "texture.hpp"
#include "viewport.hpp"

namespace sr {

struct SetupChunk;
struct TileScratch;

// What the alpha test of one masked draw reads. The fragment's alpha is the draw colour's alpha
// (or, where the mesh has vertex colours, their perspective-correct interpolated alpha) times
// the base colour texture's alpha at the fragment's uv, sampled exactly as shading samples it
// (the same uv, derivatives and filter); kept iff alpha >= cutoff (glTF: NaN is discarded).
struct AlphaTest {
  const MeshData* mesh = nullptr;
  const Texture* texture = nullptr;  // null: no texture alpha (vertex alpha only)
  TextureFilter filter = TextureFilter::Nearest;
  float alpha = 1.0f;                // the draw colour's, where the mesh has no vertex colours
  float cutoff = 0.5f;
  uint8_t uv_periodic_axes = 0;      // the material's (interp::reduce_uv_period), as shading uses
};

// What a draw's material makes of it: drawn opaque (no test), masked, or not drawn at all (a
// constant alpha below the cutoff). `filter_override` is RenderOptions::texture_filter.
// Blended: glTF alphaMode BLEND with an alpha that varies or is in (0, 1) (blend.hpp).
enum class AlphaKind : uint8_t { Opaque, Masked, Invisible, Blended };
AlphaKind alpha_kind(const Draw& draw, uint8_t filter_override, AlphaTest& test);

// Rasterizes record `record` of `chunk` (a masked draw's, with its TriangleShading) over pixels
// [x0, x1] x [y0, y1] of the tile at `rect`, sampled at (sample_x, sample_y) from each pixel's
// corner, as raster::rasterize_large does (the same edge tests and depth keys) but keeping only
// fragments that pass the alpha test; a discarded fragment is not counted in `coverage` either.
// Returns whether the triangle won a pixel.
bool rasterize_masked(const AlphaTest& test, const SetupChunk& chunk, uint32_t record, int x0,
                      int x1, int y0, int y1, const TileRect& rect, uint32_t index,
                      int32_t sample_x, int32_t sample_y, bool coverage, TileScratch& s);

}  // namespace sr
