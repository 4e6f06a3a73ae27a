// RenderPlan: every flag a render derives from its options, computed once before any stage runs
// (make_plan) and read by the stages; no stage re-derives one from which buffers happen to exist.
#pragma once

#include "pipeline.hpp"
#include "shade_models.hpp"

#include <cstddef>
#include <cstdint>

namespace sr {

struct RenderPlan {
  uint32_t outputs = 0;       // OutputBit set
  bool color = false;         // outputs requested
  bool normal = false;
  bool coverage = false;
  bool shade = false;         // colour or normals: setup writes TriangleShading, tiles shade
  bool surface = false;       // surface outputs (kSurfaceOutputs): setup writes TriangleShading
  bool estimate_overdraw = false;  // "auto" path: setup estimates each tile's overdraw
  bool forward_allowed = false;    // forward shading may be used (shading, not "deferred", no
                                   // coverage counting, not scanline)
  bool scanline = false;      // triangles filled by edge walking (RasterAlgorithm::Scanline)
  bool stream = false;        // outputs written with non-temporal stores (outputs.hpp)
  std::size_t bytes = 0;      // of every requested output
  Shading shading = Shading::Lambert;
};

RenderPlan make_plan(const RenderOptions& options, int width, int height);

}  // namespace sr
