// Framebuffer allocation. Buffers are not cleared here: the tile pass writes every pixel.
#include "framebuffer.hpp"

namespace sr {

const OutputLayout kOutputLayouts[kNumOutputs] = {
    {kOutColor, "color", 3, 1},           {kOutDepth, "depth", 1, 4},
    {kOutMask, "mask", 1, 1},             {kOutNormal, "normal", 3, 4},
    {kOutTriangleId, "triangle_id", 1, 4}, {kOutInstanceId, "instance_id", 1, 4},
    {kOutCoverage, "coverage", 1, 4},
};
const char* const kOutputNames[kNumOutputs] = {"color",       "depth",       "mask",    "normal",
                                               "triangle_id", "instance_id", "coverage"};

std::size_t Framebuffer::bytes_needed(int width, int height, uint32_t outputs) {
  std::size_t total = 0;
  for (const OutputLayout& layout : kOutputLayouts)
    if (outputs & layout.bit)
      total += std::size_t(width) * std::size_t(height) * layout.channels * layout.item_bytes;
  return total;
}

Framebuffer::Framebuffer(int w, int h, uint32_t out) : width(w), height(h), outputs(out) {
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& layout = kOutputLayouts[i];
    if (!(outputs & layout.bit)) continue;
    const std::size_t bytes = std::size_t(w) * h * layout.channels * layout.item_bytes;
    buffers_[i].reset(new std::byte[bytes > 0 ? bytes : 1]);  // default-init: no clearing pass
  }
  color = reinterpret_cast<uint8_t*>(buffers_[0].get());
  depth = reinterpret_cast<float*>(buffers_[1].get());
  mask = reinterpret_cast<bool*>(buffers_[2].get());
  normal = reinterpret_cast<float*>(buffers_[3].get());
  triangle_id = reinterpret_cast<int32_t*>(buffers_[4].get());
  instance_id = reinterpret_cast<int32_t*>(buffers_[5].get());
  coverage = reinterpret_cast<uint32_t*>(buffers_[6].get());
}

}  // namespace sr
