// Rasterizing triangles given in clip space (softrast.nv, nvdiffrast's rasterize): the core's own
// clipping (clip.hpp, ClipSpacePlanes: -w <= z <= w and the guard band), snapping (vertex.hpp,
// project), setup and binning (setup.hpp, bin.hpp) and tile raster (rasterize.hpp) on positions the
// caller computed, then per covered pixel nvdiffrast's outputs from the source triangle's corners.
//
// Conventions (nvdiffrast's, python/softrast/nv/__init__.py states them): image row 0 at the
// BOTTOM (NDC y = -1); pixel (row r, column c) sampled at NDC (2 (c + 1/2) / W - 1,
// 2 (r + 1/2) / H - 1); rast = (u, v, z/w, id + 1) with u, v the perspective-correct weights of
// the triangle's first two corners (clamped to [0, 1]), z/w clamped to [-1, 1] and id + 1 stored
// as nvdiffrast stores it in a float (exact up to 2^24, then the bits of 0x4a800000 + id);
// rast_db = (du/dX, du/dY, dv/dX, dv/dY) per pixel step right and up. All 0 where no triangle is
// seen. The depth test keeps the nearest z/w (key -(z/w + 2): orthographic keys, the tile pass's
// orthographic tie factor, so an earlier triangle within 2^-20 of the depth stays); both windings
// are drawn. Coverage and visibility are the core's exact fixed-point raster; the outputs are
// computed in double from the source triangle's clip-space corners at the pixel centre (the
// same formulas as nvdiffrast's rasterize.cu) and rounded to float32 once: the same bits for any
// thread count and either instruction set.
#pragma once

#include "simd.hpp"

#include <cstdint>

namespace sr {

struct ClipRasterInput {
  const float* pos = nullptr;  // (pos_images, num_vertices, 4) clip-space x, y, z, w
  int64_t pos_images = 1;      // 1: every image draws these positions (range mode), else images
  int64_t num_vertices = 0;
  const int32_t* tri = nullptr;  // (num_triangles, 3), each index in [0, num_vertices)
  int64_t num_triangles = 0;
  const int64_t* ranges = nullptr;  // (images, 2): image k draws tri[first, first + count)
  int64_t images = 0;
  int width = 0, height = 0;
};

// Writes rast (images, height, width, 4) and, if not null, rast_db (the same shape), every value
// of both. Throws std::invalid_argument for inputs outside the rules above (sizes, indices,
// ranges), std::runtime_error like ThreadPool when the system refuses a thread. threads == 0:
// one per core.
void rasterize_clip(const ClipRasterInput& in, float* rast, float* rast_db, int threads, Isa isa);

}  // namespace sr
