// Renderer: orchestrates the stages over a persistent thread pool.
//   vertices (parallel over vertex blocks) -> setup + binning (parallel over triangle chunks)
//   -> rasterize + shade (parallel over screen tiles, each owned by one thread)
#pragma once

#include "blend.hpp"
#include "framebuffer.hpp"
#include "lines.hpp"
#include "multisample.hpp"
#include "pipeline.hpp"
#include "rasterize.hpp"
#include "scratch.hpp"
#include "setup.hpp"
#include "shade.hpp"
#include "shadow.hpp"
#include "thread_pool.hpp"

#include <memory>
#include <mutex>
#include <vector>

namespace sr {

class Renderer {
 public:
  // Throws std::invalid_argument for sizes outside [1, kMaxImageSide] or threads outside
  // [0, kMaxThreads], std::runtime_error when the system refuses a worker thread (ThreadPool).
  // `simd`: use the best instruction set the CPU has (false: the generic kernels; the images are
  // the same bits).
  Renderer(int width, int height, int threads, bool simd = true);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  int width() const { return viewport_.width; }
  int height() const { return viewport_.height; }
  int threads() const { return pool_.size(); }
  Isa isa() const { return isa_; }

  // Renders the draws in order into a new framebuffer holding only options.outputs.
  // Thread-safe: concurrent calls on one Renderer run one after the other. fork() waits for
  // renders in progress to end (so the child inherits no render half done and no lock held);
  // a render must therefore never wait for the thread that forks (e.g. for Python's GIL).
  // Throws std::invalid_argument for an invalid camera, options or draw.
  // `external` (optional, indexed like kOutputLayouts) supplies caller memory for some outputs.
  // `primitives`: lines and points drawn over the triangles (lines.hpp), lines by
  // `line_algorithm`.
  std::unique_ptr<Framebuffer> render(const std::vector<Draw>& draws, const CameraParams& camera,
                                      const RenderOptions& options,
                                      std::byte* const* external = nullptr,
                                      const std::vector<PrimitiveDraw>& primitives = {},
                                      LineAlgorithm line_algorithm = LineAlgorithm::Bresenham);

  // Where released output buffers wait for the next render (framebuffer.hpp): it holds up to
  // two frames of the largest size rendered. Shared: a buffer may outlive the renderer.
  const std::shared_ptr<BufferPool>& buffer_pool() const { return buffer_pool_; }

 private:
  Viewport viewport_;
  ThreadPool pool_;
  Isa isa_;
  std::mutex mutex_;  // held for a whole render, and by fork() (see renderer.cpp)
  // Scratch reused across renders: no per-frame allocation once sizes settle.
  std::vector<ScratchArray<ProjectedVertex>> vertices_;  // per draw
  std::vector<SetupChunk> chunks_;
  std::vector<ScratchArray<vec3>> world_normals_;  // per draw, when shading needs them
  // Per worker, allocated by the worker itself on its first tile: first touched in parallel,
  // and only by workers that take part (ThreadPool::parallel_for).
  std::vector<std::unique_ptr<TileScratch>> tile_scratch_;
  std::vector<std::unique_ptr<ShadeScratch>> shade_scratch_;
  std::vector<std::unique_ptr<MultisampleScratch>> multisample_scratch_;  // anti-aliased renders
  std::vector<std::unique_ptr<BlendScratch>> blend_scratch_;  // renders with blended draws
  PrimitiveSetup primitives_;  // lines and points, set up (lines.hpp)
  ShadowScene shadows_;        // occluders of shadowed lights (renders with one)
  std::vector<std::unique_ptr<PrimitivePixels>> primitive_pixels_;  // per worker, on first use
  std::shared_ptr<BufferPool> buffer_pool_ = std::make_shared<BufferPool>(0);
};

void validate_camera(const CameraParams& camera);

}  // namespace sr
