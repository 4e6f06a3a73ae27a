// Framebuffer: one freshly allocated buffer per requested output, handed over without a copy.
#pragma once

#include "pipeline.hpp"

#include <cstddef>
#include <memory>
#include <new>

namespace sr {

struct OutputLayout {
  OutputBit bit;
  const char* name;
  int channels;          // 1 => (h, w), else (h, w, channels)
  std::size_t item_bytes;  // bytes of one channel value
};
extern const OutputLayout kOutputLayouts[kNumOutputs];

// Output buffers start on a cache line: the tile pass's threads write neighbouring tiles' rows,
// and with rows a whole number of lines wide (a width divisible by 64 / bytes per pixel) no line
// is then written by two threads.
constexpr std::size_t kFrameAlign = 64;

// One output's buffer, uninitialised, kFrameAlign-aligned; free_frame_buffer() frees it (as does
// FrameBufferPtr), also after Framebuffer::release() gave it up.
inline std::byte* allocate_frame_buffer(std::size_t bytes) {
  return static_cast<std::byte*>(::operator new[](bytes, std::align_val_t(kFrameAlign)));
}
inline void free_frame_buffer(std::byte* p) { ::operator delete[](p, std::align_val_t(kFrameAlign)); }
struct FreeFrameBuffer {
  void operator()(std::byte* p) const { free_frame_buffer(p); }
};
using FrameBufferPtr = std::unique_ptr<std::byte[], FreeFrameBuffer>;

class Framebuffer {
 public:
  // Bytes the requested outputs need; checked against kMaxFramebufferBytes before allocating.
  static std::size_t bytes_needed(int width, int height, uint32_t outputs);

  // Allocates a buffer for each requested output, except where `external[i]` (indexed like
  // kOutputLayouts) supplies the caller's own memory of the right size, which it writes into.
  Framebuffer(int width, int height, uint32_t outputs, std::byte* const* external = nullptr);

  // Gives up ownership of one output's allocated buffer (the caller frees it with
  // free_frame_buffer); nullptr for an output written into external memory.
  std::byte* release(int layout_index) { return buffers_[layout_index].release(); }

  int width, height;
  uint32_t outputs;
  // Row-major, row 0 = top. Null when not requested. Every pixel is written by the render.
  uint8_t* color = nullptr;
  float* depth = nullptr;
  bool* mask = nullptr;
  float* normal = nullptr;
  int32_t* triangle_id = nullptr;
  int32_t* instance_id = nullptr;
  uint32_t* coverage = nullptr;

 private:
  FrameBufferPtr buffers_[kNumOutputs];
};

}  // namespace sr
