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

Framebuffer::Framebuffer(int w, int h, uint32_t out, std::byte* const* external)
    : width(w), height(h), outputs(out) {
  std::byte* data[kNumOutputs] = {};
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& layout = kOutputLayouts[i];
    if (!(outputs & layout.bit)) continue;
    if (external && external[i]) {
      data[i] = external[i];
      continue;
    }
    const std::size_t bytes = std::size_t(w) * h * layout.channels * layout.item_bytes;
    buffers_[i].reset(allocate_frame_buffer(bytes));  // not cleared: the tile pass writes every pixel
    data[i] = buffers_[i].get();
  }
  color = reinterpret_cast<uint8_t*>(data[0]);
  depth = reinterpret_cast<float*>(data[1]);
  mask = reinterpret_cast<bool*>(data[2]);
  normal = reinterpret_cast<float*>(data[3]);
  triangle_id = reinterpret_cast<int32_t*>(data[4]);
  instance_id = reinterpret_cast<int32_t*>(data[5]);
  coverage = reinterpret_cast<uint32_t*>(data[6]);
}

}  // namespace sr
