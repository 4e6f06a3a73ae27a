// Framebuffer allocation. Buffers are not cleared here: the tile pass writes every pixel.
#include "framebuffer.hpp"

namespace sr {

std::size_t Framebuffer::bytes_needed(int width, int height, uint32_t outputs) {
  std::size_t total = 0;
  for (const OutputLayout& layout : kOutputLayouts)
    if (outputs & layout.bit) total += std::size_t(width) * std::size_t(height) * layout.bytes_per_pixel();
  return total;
}

Framebuffer::Framebuffer(int w, int h, uint32_t out, std::byte* const* external)
    : width(w), height(h), outputs(out) {
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& layout = kOutputLayouts[i];
    if (!(outputs & layout.bit)) continue;
    if (external && external[i]) {
      data_[i] = external[i];
      continue;
    }
    const std::size_t bytes = std::size_t(w) * h * layout.bytes_per_pixel();
    buffers_[i].reset(allocate_frame_buffer(bytes));  // not cleared: the tile pass writes every pixel
    data_[i] = buffers_[i].get();
  }
}

}  // namespace sr
