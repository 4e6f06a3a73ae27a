// Framebuffer allocation. Buffers are not cleared here: the tile pass writes every pixel.
#include "framebuffer.hpp"

#include <algorithm>

namespace sr {

std::size_t Framebuffer::bytes_needed(int width, int height, uint32_t outputs) {
  std::size_t total = 0;
  for (const OutputLayout& layout : kOutputLayouts)
    if (outputs & layout.bit) total += std::size_t(width) * std::size_t(height) * layout.bytes_per_pixel();
  return total;
}

BufferPool::~BufferPool() {
  for (auto& [bytes, p] : free_) free_frame_buffer(p);
}

std::byte* BufferPool::take(std::size_t bytes) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (std::size_t i = free_.size(); i-- > 0;) {
      if (free_[i].first != bytes) continue;
      std::byte* p = free_[i].second;
      free_.erase(free_.begin() + std::ptrdiff_t(i));
      cached_ -= bytes;
      return p;
    }
  }
  return allocate_frame_buffer(bytes);
}

void BufferPool::give(std::byte* p, std::size_t bytes) {
  std::vector<std::byte*> drop;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    free_.emplace_back(bytes, p);
    cached_ += bytes;
    while (cached_ > max_bytes_ && !free_.empty()) {  // the oldest go first
      cached_ -= free_.front().first;
      drop.push_back(free_.front().second);
      free_.erase(free_.begin());
    }
  }
  for (std::byte* q : drop) free_frame_buffer(q);
}

void BufferPool::hold_at_least(std::size_t bytes) {
  std::lock_guard<std::mutex> lock(mutex_);
  max_bytes_ = std::max(max_bytes_, bytes);
}

Framebuffer::Framebuffer(int w, int h, uint32_t out, std::byte* const* external, BufferPool* pool)
    : width(w), height(h), outputs(out) {
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& layout = kOutputLayouts[i];
    if (!(outputs & layout.bit)) continue;
    if (external && external[i]) {
      data_[i] = external[i];
      continue;
    }
    const std::size_t bytes = std::size_t(w) * h * layout.bytes_per_pixel();
    // not cleared: the tile pass writes every pixel
    buffers_[i].reset(pool ? pool->take(bytes) : allocate_frame_buffer(bytes));
    data_[i] = buffers_[i].get();
  }
}

}  // namespace sr
