// Scanline fill (render(raster="scanline")): each row's span of covered pixels found by edge
// walking, the classical algorithm, as a second, independent rasterizer of the same coverage
// rule as the edge-function kernels (rasterize.hpp). Scalar and out of line (scanline.cpp,
// compiled once for the generic target: the same bits under either instruction set's kernels);
// the default path never branches on it (raster::rasterize_all's kScanline, once per render).
#pragma once

#include "pipeline.hpp"
#include "viewport.hpp"

namespace sr {

struct TileScratch;

// Rasterizes `t` over pixels [x0, x1] x [y0, y1] of the tile at `rect`, sampled at (sample_x,
// sample_y) from each pixel's corner: each row's span [xl, xr] is the intersection of the bounds
// its three edges put on x, walked from row to row in exact integers; its pixels are counted in
// `coverage` (if asked) and depth-tested with the same keys as raster::rasterize_large. It covers
// exactly the samples the edge functions cover (the same snapped vertices and top-left rule),
// so both give the same bits. Returns whether the triangle won a pixel.
bool rasterize_scanline(const TriangleSetup& t, int x0, int x1, int y0, int y1,
                        const TileRect& rect, uint32_t index, int32_t sample_x, int32_t sample_y,
                        bool coverage, TileScratch& s);

}  // namespace sr
