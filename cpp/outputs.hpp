// Outputs: a tile's resolved values (visibility, depth keys, shaded scratch) copied to the
// requested framebuffers, background where nothing is visible. The only writer of output memory.
#pragma once

#include "shade.hpp"

namespace sr {

struct BlendScratch;  // blend.hpp

// Frames of at least this many output bytes are written with non-temporal stores: they spare a
// large frame the read of every line it overwrites, while a small frame, which stays in cache
// from one render to the next, gets slower with them (benchmarks/RESULTS.md, "Measurements
// behind the code").
constexpr std::size_t kStreamFrameBytes = std::size_t(12) << 20;

struct ResolvedSamples;  // multisample.hpp
struct PrimitivePixels;  // lines.hpp

// Copies the tile's values to every requested output of params.framebuffer. `samples` (null
// without anti-aliasing) gives a multisampled tile's alpha, premultiplied radiance, coverage and
// each pixel's representative sample, where its surface outputs are read; `raster` then holds
// the representative's entries and `shaded` the colour output's linear values. `primitives`
// (null unless lines or points were drawn into the tile, lines.hpp) holds the instance id and
// world position of each pixel whose entry is kPrimitivePixel. `blend` (null unless blended
// fragments were composited in the tile, blend.hpp): the colour, radiance and alpha outputs
// from its planes (never with `samples`).
void write_tile(const ShadeParams& params, const TileRect& rect, const TileScratch& raster,
                const ShadeScratch& shaded, Isa isa, const ResolvedSamples* samples = nullptr,
                const PrimitivePixels* primitives = nullptr, const BlendScratch* blend = nullptr);

}  // namespace sr
