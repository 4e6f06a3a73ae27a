// Framebuffer: one freshly allocated buffer per requested output, handed over without a copy.
#pragma once

#include "pipeline.hpp"

#include <cstddef>
#include <memory>
#include <mutex>
#include <new>
#include <utility>
#include <vector>

namespace sr {

// Element types of outputs (NumPy's names in bindings.cpp).
enum class DType : uint8_t { U8, Bool, I32, U32, F32 };
constexpr std::size_t dtype_bytes(DType t) {
  return t == DType::U8 || t == DType::Bool ? 1 : 4;
}
// Which pass writes an output: the resolve of the tile's visibility buffer (depth keys, ids,
// coverage), shading (colour, normals: forward or deferred, then copied by write_tile), or the
// visible surface point, found from the visibility buffer when the tile is written (barycentric
// weights and what they interpolate).
enum class OutputPass : uint8_t { Resolve, Shade, Surface };

// The output table: one row per output, the one place that says what an output is. Bindings,
// the Python package (softrast.OUTPUT_TABLE: render.py's lists, Frame, the memory budget, the
// tests) and the framebuffer derive everything from it. Adding an output is a row here and in
// OutputBit, and its writer in outputs.cpp (ARCHITECTURE.md, "Add an output").
struct OutputLayout {
  OutputBit bit;
  const char* name;
  DType dtype;
  int channels;            // 1 => (h, w), else (h, w, channels)
  std::size_t item_bytes;  // bytes of one channel value (dtype_bytes(dtype))
  double background;       // value of every channel where nothing is drawn (colour: the
                           // render's background option instead)
  OutputPass pass;
  const char* doc;         // shape, dtype, unit and meaning, for docstrings
  constexpr std::size_t bytes_per_pixel() const { return std::size_t(channels) * item_bytes; }
};
inline constexpr OutputLayout kOutputLayouts[kNumOutputs] = {
    {kOutColor, "color", DType::U8, 3, 1, 0.0, OutputPass::Shade,
     "(h, w, 3) uint8: shaded colour, row 0 = top of the image; the background colour where "
     "nothing is hit. The radiance clamped to [0, 1] and sRGB-encoded (render(srgb=False): "
     "linear), rounded to nearest"},
    {kOutDepth, "depth", DType::F32, 1, 4, 0.0, OutputPass::Resolve,
     "(h, w) float32: distance along the camera's viewing axis (-z_view) in scene units, 0 where "
     "nothing was hit (orthographic cameras included)"},
    {kOutMask, "mask", DType::Bool, 1, 1, 0.0, OutputPass::Resolve,
     "(h, w) bool: True where a triangle covers the pixel centre (with msaa/ssaa: any of its "
     "samples)"},
    {kOutNormal, "normal", DType::F32, 3, 4, 0.0, OutputPass::Shade,
     "(h, w, 3) float32: world-space unit normal of the visible side, 0 = background"},
    {kOutTriangleId, "triangle_id", DType::I32, 1, 4, -1.0, OutputPass::Resolve,
     "(h, w) int32: face index within its mesh, -1 = background"},
    {kOutInstanceId, "instance_id", DType::I32, 1, 4, -1.0, OutputPass::Resolve,
     "(h, w) int32: the instance's id from Scene.add, -1 = background"},
    {kOutCoverage, "coverage", DType::U32, 1, 4, 0.0, OutputPass::Resolve,
     "(h, w) uint32: number of rasterized triangles covering the pixel centre before the depth "
     "test (a closed convex mesh with back-face culling gives exactly 1); with msaa/ssaa summed "
     "over the pixel's samples"},
    {kOutRadiance, "radiance", DType::F32, 3, 4, 0.0, OutputPass::Shade,
     "(h, w, 3) float32: shaded linear RGB radiance, unclamped, 0 = background (the colour "
     "output is this, clamped and encoded)"},
    {kOutBarycentric, "barycentric", DType::F32, 3, 4, 0.0, OutputPass::Surface,
     "(h, w, 3) float32: barycentric weights of the visible point in its mesh face, where the "
     "pixel's own ray meets the face (weights of the face's corners faces[triangle_id] in order; "
     "of the whole face where clipping cut it), summing to 1, in [0, 1] but for the raster's "
     "1/512 px snap over the triangle's height; 0 = background"},
    {kOutUv, "uv", DType::F32, 2, 4, 0.0, OutputPass::Surface,
     "(h, w, 2) float32: the mesh's uvs interpolated at the visible point (perspective-correct; "
     "0 where the mesh has none), 0 = background"},
    {kOutPosition, "position", DType::F32, 3, 4, 0.0, OutputPass::Surface,
     "(h, w, 3) float32: world-space position of the visible point, where the pixel's own ray "
     "meets its face (the barycentric weights applied to the face's posed corners), 0 = "
     "background"},
    {kOutRayDepth, "ray_depth", DType::F32, 1, 4, 0.0, OutputPass::Surface,
     "(h, w) float32: Euclidean distance from the camera centre to the visible point in scene "
     "units (orthographic cameras: from the image plane along the rays, = depth), 0 = "
     "background"},
    {kOutAlpha, "alpha", DType::F32, 1, 4, 0.0, OutputPass::Resolve,
     "(h, w) float32: fraction of the pixel's samples covered, in [0, 1] (without anti-aliasing "
     "1 where the pixel centre is covered, else 0); radiance is premultiplied by it"},
};

constexpr bool output_table_is_consistent() {
  for (int i = 0; i < kNumOutputs; ++i)
    if (uint32_t(kOutputLayouts[i].bit) != 1u << i ||
        kOutputLayouts[i].item_bytes != dtype_bytes(kOutputLayouts[i].dtype))
      return false;
  return true;
}
static_assert(output_table_is_consistent(), "rows in bit order, item sizes matching dtypes");
// The row of an output bit (exactly one bit set).
inline int output_index(OutputBit bit) { return __builtin_ctz(uint32_t(bit)); }

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

// Output buffers the user has released, kept for the next renders of the same size: a fresh
// allocation pays a page fault per 4 KiB on its first write, which made a default render of a
// large frame much slower than one into out= (benchmarks/RESULTS.md, "Measurements behind the
// code"). A buffer comes back only when nothing views it any more (bindings.cpp: the NumPy
// array's capsule gives it back), so a frame the user still holds is never written. Holds at
// most `max_bytes`; the rest is freed. Thread-safe.
class BufferPool {
 public:
  explicit BufferPool(std::size_t max_bytes) : max_bytes_(max_bytes) {}
  ~BufferPool();
  BufferPool(const BufferPool&) = delete;
  BufferPool& operator=(const BufferPool&) = delete;
  // A released buffer of exactly `bytes` (already paged in), or a new one.
  std::byte* take(std::size_t bytes);
  // Keeps `p` (`bytes` long, from allocate_frame_buffer) for take(), or frees it when full.
  void give(std::byte* p, std::size_t bytes);
  void hold_at_least(std::size_t bytes);  // raises the limit (never lowers it)

 private:
  std::mutex mutex_;
  std::vector<std::pair<std::size_t, std::byte*>> free_;  // most recently given last
  std::size_t cached_ = 0, max_bytes_;
};

class Framebuffer {
 public:
  // Bytes the requested outputs need; checked against kMaxFramebufferBytes before allocating.
  static std::size_t bytes_needed(int width, int height, uint32_t outputs);

  // Allocates a buffer for each requested output (from `pool` where it has one of the size),
  // except where `external[i]` (indexed like kOutputLayouts) supplies the caller's own memory of
  // the right size, which it writes into.
  Framebuffer(int width, int height, uint32_t outputs, std::byte* const* external = nullptr,
              BufferPool* pool = nullptr);

  // Gives up ownership of one output's allocated buffer (the caller frees it with
  // free_frame_buffer); nullptr for an output written into external memory.
  std::byte* release(int layout_index) { return buffers_[layout_index].release(); }

  // An output's memory as T (its dtype's C++ type): row-major, row 0 = top, channels
  // interleaved; null when not requested. Every pixel is written by the render.
  template <typename T>
  T* get(OutputBit bit) const { return reinterpret_cast<T*>(data_[output_index(bit)]); }
  std::byte* data(int layout_index) const { return data_[layout_index]; }

  int width, height;
  uint32_t outputs;

 private:
  std::byte* data_[kNumOutputs] = {};
  FrameBufferPtr buffers_[kNumOutputs];
};

}  // namespace sr
