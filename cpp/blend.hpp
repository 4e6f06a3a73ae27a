// Alpha blending (glTF alphaMode BLEND), exact and independent of draw order.
//
// A blended draw (alpha_kind: AlphaKind::Blended) is set up and binned like any other, but its
// chunks sit after the opaque ones and the opaque tile pass never reads them. After a tile's
// opaque surfaces (and lines and points) are resolved and shaded, blend_tile peels the blended
// fragments in front of them, nearest first:
//  - one walk over the tile's blended records keeps, per pixel, the kBlendLayers nearest
//    fragments behind the previous walk's last (a k-buffer: gather_blended, alpha_mask.cpp, the
//    same scalar edge tests and depth keys as the raster's int64 path, and each kept fragment's
//    alpha, computed as the alpha test computes it);
//  - those layers are shaded together by the render's deferred kernel (its passes: each
//    triangle prepared once for all of them), colour only;
//  - and composited front to back in linear light: C += T a c, T *= 1 - a.
// Walks repeat until no pixel has more fragments (or every such pixel's transmittance is 0), so
// any number of layers is exact in bounded memory (BlendScratch, per worker).
//
// Order: a fragment is in front of the opaque surface as the depth test would decide between
// them (draw order on a tie, kTieFactor*), and so are blended fragments ordered among themselves
// (blend_before): nearer first, fragments at equal depth (within 2^-20) in draw order, so
// coplanar layers composite in the order they were drawn.
//
// With ssaa and msaa, multisample_tile runs this per sample (each sample's opaque raster, the
// layers walked and shaded at that sample's position) and averages the composites; msaa's
// opaque shade, shared by a triangle's samples, is weighted by each one's transmittance.
//
// Outputs (the README states them): colour and radiance are composited (radiance premultiplied:
// nothing behind counts 0; colour over the background's linear value); alpha is the total
// coverage, 1 - the transmittance where no opaque surface is seen; depth, ids, mask, normal and
// the surface outputs are the nearest opaque surface's, and coverage counts opaque fragments.
// With an alpha threshold (RenderOptions::alpha_threshold), the nearest blended fragment in front
// whose alpha (clamped to [0, 1]) reaches it stands for the surface instead: blend_tile records
// it (BlendScratch::hit), take_blend_surfaces makes it the pixel's entry before write_tile, and
// with anti-aliasing the pixel's representative is the sample nearest the centre that sees such
// a fragment or an opaque surface (blend_surface_sample).
#pragma once

#include "alpha_mask.hpp"
#include "shade.hpp"

#include <cstring>
#include <vector>

namespace sr {

constexpr int kBlendLayers = kMaxShadePasses;

// Whether fragment (key a, tile index ia) composites before (in front of) fragment (b, ib) of
// the same pixel: the depth test's own rule between the two (rasterize.hpp): the later drawn one
// is in front only if its key beats the earlier one's by the tie factor. So fragments at equal
// depth (within 2^-20) composite in draw order, as the depth test keeps the first drawn.
inline bool blend_before(float a, uint32_t ia, float b, uint32_t ib, float tie) {
  return ia < ib ? !(b > a * tie) : a > b * tie;
}

// Per-thread scratch of the blend pass, allocated on a worker's first tile with a blended draw.
struct BlendScratch {
  // The k-buffer of a walk: per pixel, its `count` fragments nearest first, each with its alpha
  // and (in layer[l]) key and index; a later walk takes only fragments behind the previous
  // walk's last (`floor_key`, `floor_index`: blend_before). `total`: the pixel's fragments in
  // front of the opaque surface (counted by the first walk), `taken`: those composited; a pixel
  // is done when they are equal (which also bounds the walks where keys within the tie factor
  // of each other form a chain that the rule does not order transitively).
  float alpha_of[kBlendLayers][kTilePixels];
  float floor_key[kTilePixels];
  uint32_t floor_index[kTilePixels];
  uint32_t total[kTilePixels];
  uint32_t taken[kTilePixels];
  uint8_t count[kTilePixels];
  TileRect box;  // the tile's pixels its blended records may cover (blend_tile), half-open
  TileScratch layer[kBlendLayers];   // layer[0].triangles: the tile's blended records, in order
  ShadeScratch shaded[kBlendLayers];
  float transmit[kTilePixels];
  float sum[3][kTilePixels];
  bool touched[kTilePixels];
  // The tile's composited outputs (row stride kTileSizePx), read by write_tile.
  float color[3][kTileScratchPixels];     // linear, over the opaque surface or the background
  float radiance[3][kTileScratchPixels];  // premultiplied
  float alpha[kTileScratchPixels];
  uint32_t seen[kTileScratchPixels];      // kNoTriangle where nothing at all is seen
  // With an alpha threshold: per pixel, the nearest fragment reaching it (an index into
  // layer[0].triangles, or kNoTriangle), its key and (when normals are shaded) its normal.
  uint32_t hit[kTileScratchPixels];
  float hit_key[kTileScratchPixels];
  float hit_normal[3][kTileScratchPixels];
  // Anti-aliasing: the pixel's best such fragment over the samples so far (blend_surface_sample):
  // the rank of its sample in the representative order (kNoRank: none), the fragment, key and
  // normal.
  static constexpr uint8_t kNoRank = 0xff;
  uint8_t best_rank[kTileScratchPixels];
  uint32_t best[kTileScratchPixels];  // an index into layer[0].triangles
  float best_key[kTileScratchPixels];
  float best_normal[3][kTileScratchPixels];
};

// One walk over blended chunks [begin, end) of `tile` (tests: each draw's alpha, by draw
// index): fills the k-buffer of `s` within s.box. `first`: also lists the tile's blended records in
// s.layer[0].triangles. Returns the most fragments a pixel kept (0: none left).
int gather_blended(const std::vector<SetupChunk>& chunks, std::size_t begin, std::size_t end,
                   int tile, const TileRect& rect, const AlphaTest* const* tests,
                   const TileScratch& opaque, bool first, BlendScratch& s);

struct BlendParams {
  const ShadeParams* shade;  // the layers' shading (colour only), or null: alpha alone
  const TileKernels* kernels;
  const std::vector<SetupChunk>* chunks;
  std::size_t begin, end;    // the blended chunks
  const AlphaTest* const* tests;
  vec3 background_linear;    // the colour output's background, linear (renderer.cpp)
  bool surfaces = false;     // record the nearest fragment whose alpha reaches `threshold`
  float threshold = 1.0f;
  bool normals = false;      // ... and its normal (`shade` computes the normal output)
};

// Composites the tile's blended fragments over `opaque` (resolved, with its shade `opaque_shade`
// where colour is shaded) into s.color / radiance / alpha / seen. Returns false (and writes
// nothing) if no blended fragment is in front of anything in the tile.
bool blend_tile(const BlendParams& params, const TileRect& rect, int tile,
                const TileScratch& opaque, const ShadeScratch& opaque_shade, BlendScratch& s);

// After blend_tile returned true with params.surfaces: each pixel with a recorded fragment takes
// it as its entry in `raster` (the tile's blended records appended to raster.triangles), its key,
// and (params.normals) its normal in `normal`.
void take_blend_surfaces(const BlendParams& params, const TileRect& rect, const BlendScratch& s,
                         TileScratch& raster, float* const normal[3]);

// Anti-aliasing: before a tile's samples, no pixel has a fragment (best_rank = kNoRank).
void clear_blend_surfaces(const TileRect& rect, BlendScratch& s);
// After blend_tile for the sample of rank `rank` (in the representative order) returned true:
// keeps, per pixel, the fragment of the lowest-ranked sample that has one.
void blend_surface_sample(const BlendParams& params, const TileRect& rect, int rank, BlendScratch& s);
// After every sample: a pixel whose best fragment's sample ranks before its representative
// (`rank_of` the representative order's inverse; a pixel without an opaque sample has none)
// takes it, as take_blend_surfaces does, and that sample becomes its representative.
void take_blend_surfaces_multisample(const BlendParams& params, const TileRect& rect,
                                     const BlendScratch& s, const uint8_t* order,
                                     const uint8_t* rank_of, TileScratch& resolved,
                                     int32_t* representative, float* const normal[3]);

}  // namespace sr
