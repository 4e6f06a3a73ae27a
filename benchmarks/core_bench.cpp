// Drives the C++ core without Python, for callgrind and quick timing:
//   core_bench SUBDIV WIDTH HEIGHT OUTPUT_BITS RENDERS [THREADS [SIMD]]
// renders an icosphere (radius 1, seen from z = 3.4, fov 45) and prints ms per render.
#include "renderer.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>

using namespace sr;

static std::shared_ptr<MeshData> icosphere(int subdivisions) {
  MeshVectors mesh;
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  std::vector<vec3>& p = mesh.positions;
  p = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
       {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<ivec3> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int s = 0; s < subdivisions; ++s) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      p.push_back((p[a] + p[b]) * 0.5f);
      return mid[key] = int(p.size()) - 1;
    };
    std::vector<ivec3> next;
    for (const ivec3& tri : f) {
      const int a = midpoint(tri.x, tri.y), b = midpoint(tri.y, tri.z), c = midpoint(tri.z, tri.x);
      next.insert(next.end(), {{tri.x, a, c}, {tri.y, b, a}, {tri.z, c, b}, {a, b, c}});
    }
    f = std::move(next);
  }
  for (vec3& v : p) v = glm::normalize(v);
  mesh.normals = p;
  mesh.faces = std::move(f);
  auto data = MeshData::from_vectors(std::move(mesh));
  data->validate();
  return data;
}

int main(int argc, char** argv) {
  if (argc < 6) {
    std::fprintf(stderr, "usage: core_bench SUBDIV WIDTH HEIGHT OUTPUT_BITS RENDERS [THREADS [SIMD [PATH [CULL]]]]\n"
                 "  PATH: auto | forward | deferred shading; CULL: back | none\n");
    return 2;
  }
  const int sub = std::atoi(argv[1]), width = std::atoi(argv[2]), height = std::atoi(argv[3]);
  const uint32_t outputs = uint32_t(std::atoi(argv[4]));
  const int renders = std::atoi(argv[5]), threads = argc > 6 ? std::atoi(argv[6]) : 0;
  const bool simd = argc > 7 ? std::atoi(argv[7]) != 0 : true;
  const std::string path = argc > 8 ? argv[8] : "auto", cull = argc > 9 ? argv[9] : "back";

  Renderer renderer(width, height, threads, simd);
  std::vector<Draw> draws(1);
  draws[0].mesh = icosphere(sub);
  CameraParams camera;
  camera.view = dmat4(1.0);
  camera.view[3][2] = -3.4;  // camera at z = 3.4 looking down -z
  const double f = 1.0 / std::tan(glm::radians(45.0) / 2), n = 0.05, fa = 100.0;
  camera.proj = dmat4(0.0);
  camera.proj[0][0] = f * height / width;
  camera.proj[1][1] = f;
  camera.proj[2][2] = -(fa + n) / (fa - n);
  camera.proj[3][2] = -2 * fa * n / (fa - n);
  camera.proj[2][3] = -1;
  camera.near = n;
  camera.far = fa;
  RenderOptions options;
  options.outputs = outputs;
  options.shading_path = path == "forward"    ? ShadingPath::Forward
                         : path == "deferred" ? ShadingPath::Deferred
                                              : ShadingPath::Auto;
  options.cull = cull == "none" ? Cull::None : Cull::Back;
  // Frames reused across renders, as the Python benchmarks do with `out=` (a fresh frame costs
  // page faults, not rendering).
  // Aligned as the renderer's own frames are (framebuffer.hpp, kFrameAlign).
  std::vector<FrameBufferPtr> frames;
  std::byte* external[kNumOutputs] = {};
  for (int i = 0; i < kNumOutputs; ++i) {
    const OutputLayout& layout = kOutputLayouts[i];
    if (!(outputs & layout.bit)) continue;
    const std::size_t bytes = std::size_t(width) * height * layout.channels * layout.item_bytes;
    frames.emplace_back(allocate_frame_buffer(bytes));
    external[i] = frames.back().get();
  }
  double best = 1e30;
  for (int r = 0; r < renders; ++r) {
    const auto start = std::chrono::steady_clock::now();
    auto fb = renderer.render(draws, camera, options, external);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    best = std::min(best, ms);
  }
  std::printf("ico%d %dx%d outputs=%u threads=%d %s %s cull=%s faces=%zu: best %.2f ms\n", sub,
              width, height, outputs, renderer.threads(), isa_name(renderer.isa()), path.c_str(),
              cull.c_str(), draws[0].mesh->faces.size(), best);
}
