// Rasterizing triangles given in clip space (clip_raster.hpp): per image, a vertex pass (each
// position's outcode against ClipSpacePlanes, snapped where inside), setup and binning per chunk
// of triangles (clipping where a corner is outside a plane), then the tile pass (the core's raster
// kernels) and nvdiffrast's outputs at each pixel the tile's raster resolved.
#include "clip_raster.hpp"

#include "bin.hpp"
#include "clip.hpp"
#include "rasterize.hpp"
#include "setup.hpp"
#include "thread_pool.hpp"
#include "transform.hpp"
#include "vertex.hpp"
#include "viewport.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace sr {

namespace {

// The raster orders fragments by z/w + 2, in [1, 3] inside -w <= z <= w: its key -(z/w + 2) is
// an orthographic one (negative, affine in window space), which setup fits and the tile pass
// tests as it does a render's (pipeline.hpp, "depth key").
constexpr double kDepthOffset = 2.0;

// Work items, as the renderer's (renderer.cpp): vertices per vertex block; triangles per setup
// chunk, fewer for a small image so that its setup splits over two threads. Records keep
// primitive order across chunks: chunking does not change the output.
constexpr std::size_t kVertexBlock = 4096;
constexpr std::size_t kMinChunkFaces = 256;
std::size_t chunk_faces(std::size_t faces) {
  const std::size_t share = (faces + 1) / 2;
  return std::clamp((share + 7) / 8 * 8, kMinChunkFaces, std::size_t(kTriangleChunk));
}

// nvdiffrast's triangle id + 1 in a float32 channel (common.h, triidx_to_float): exact up to
// 2^24, then the bits of the integer 0x4a800000 + id.
float id_to_float(int64_t id) {
  if (id <= 0x01000000) return float(id);
  const uint32_t bits = uint32_t(id + 0x4A800000);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

// Snaps a point inside the clip volume (or a point clipping made on its boundary): window
// position from the float position, residuals and depth key from the double one.
void snap(const vec4& p, const dvec4& d, const ClipSpacePlanes& planes, const Viewport& viewport,
          ProjectedVertex& v) {
  const ExactClip exact{d.x, d.y, d.w, d.z / d.w + kDepthOffset};
  project(p, float(exact.depth), exact, planes.band, viewport, /*orthographic=*/true,
          /*snap_outside=*/true, v);
  // The caller decided each plane's side (ClipSpacePlanes); project() keeps only what cannot be
  // rasterized: w <= 0 (the clip volume's one such point is the origin: a triangle through the
  // eye, seen edge-on) or not finite.
  v.outcode = uint8_t(v.outcode & kInvalidVertex);
}

void project_vertex(const float* p4, const ClipSpacePlanes& planes, const Viewport& viewport,
                    ProjectedVertex& v) {
  const vec4 p(p4[0], p4[1], p4[2], p4[3]);
  if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && std::isfinite(p.w))) {
    v = ProjectedVertex{};
    v.outcode = kInvalidVertex;
    return;
  }
  const uint8_t code = planes.outcode(p);
  if (code != 0) {
    v = ProjectedVertex{};
    v.outcode = code;
    return;
  }
  snap(p, dvec4(p), planes, viewport, v);
}

void append(const TriangleSetup& t, int64_t area2, const Viewport& viewport, SetupChunk& out) {
  out.records.push_back(t);
  emit(t.x0, t.y0, t.x1, t.y1, double(area2), viewport, out);
}

// A triangle with a corner outside some plane in `mask`: clipped (clip.cpp, in the corners'
// double positions, which are their float ones), its polygon snapped and set up as a fan.
void clip_and_setup(const float* pos, const int32_t* face, uint8_t mask, const ClipSpacePlanes& planes,
                    const SetupParams& params, uint32_t prim, SetupChunk& out) {
  ClipPoint in[3];
  for (int k = 0; k < 3; ++k) {
    const float* p = pos + 4 * std::size_t(face[k]);
    in[k].p_clip = vec4(p[0], p[1], p[2], p[3]);
    in[k].p_clip_d = dvec4(in[k].p_clip);
    in[k].depth_view = p[3];  // a payload clipping interpolates (ClipSpacePlanes read none)
    in[k].depth_view_d = double(p[3]);
    in[k].bary_source = vec3(0.0f);
    in[k].bary_source[k] = 1.0f;
  }
  ClipPoint poly[kMaxClipPoints];
  const int n = clip_triangle(in, mask, planes, poly);
  if (n < 3) return;
  ProjectedVertex projected[kMaxClipPoints];
  for (int i = 0; i < n; ++i) {
    snap(poly[i].p_clip, poly[i].p_clip_d, planes, params.viewport, projected[i]);
    if (projected[i].outcode & kInvalidVertex) return;  // Unrepresentable after clipping => drop.
  }
  setup_fan(projected, poly, n, params, prim, out);  // params.shade is false: records only
}

// Triangles [begin, end) of tri, set up and binned into `out` (cleared first). Each record's prim
// is its index in tri.
void setup_clip_chunk(const float* pos, const int32_t* tri, const ProjectedVertex* vertices,
                      const ClipSpacePlanes& planes, const SetupParams& params, std::size_t begin,
                      std::size_t end, SetupChunk& out) {
  out.alpha = nullptr;
  out.records.clear();
  out.shading.clear();
  out.exact.clear();
  out.record_tiles.clear();
  out.clip_bary.clear();
  out.tile_area.clear();
  out.tile_begin.assign(std::size_t(params.viewport.num_tiles()) + 2, 0);
  for (std::size_t f = begin; f < end; ++f) {
    const int32_t* face = tri + 3 * f;
    const ProjectedVertex* const v[3] = {&vertices[face[0]], &vertices[face[1]], &vertices[face[2]]};
    const uint8_t any_out = v[0]->outcode | v[1]->outcode | v[2]->outcode;
    if (any_out & kInvalidVertex) continue;  // not finite, or through the eye => drop
    if (v[0]->outcode & v[1]->outcode & v[2]->outcode) continue;  // all outside one plane => cull
    if (any_out == 0) {
      TriangleSetup t;
      TriangleShading a;
      ExactWeights e;
      int64_t area2;
      if (setup_triangle(v, params, uint32_t(f), nullptr, t, a, e, area2))
        append(t, area2, params.viewport, out);
    } else {
      clip_and_setup(pos, face, any_out, planes, params, uint32_t(f), out);
    }
  }
  bin_records(params.viewport, out);
}

inline double clamp(double v, double lo, double hi) { return v < lo ? lo : v > hi ? hi : v; }

// nvdiffrast's outputs at the pixel centre (X, Y) in NDC of triangle `prim` (corners `face`):
// with p_i = (x_i, y_i, z_i, w_i) its clip-space corners, the edge functions a_i of x_i - X w_i
// and y_i - Y w_i (rasterize.cu) give the perspective-correct weights b_i = a_i / sum(a). Each a_i
// is affine in (X, Y), so the derivatives are exact: d b_i / dX = (a_i' - b_i sum(a')) / sum(a)
// times dX / dcolumn = 2 / W (2 / H for rows). Values beyond float32's range round to inf (a
// sliver seen edge-on), as nvdiffrast's would be.
void shade_pixel(const float* pos, const int32_t* face, uint32_t prim, double X, double Y,
                 double step_x, double step_y, float* r, float* db) {
  double x[3], y[3], z[3], w[3], px[3], py[3];
  for (int k = 0; k < 3; ++k) {
    const float* p = pos + 4 * std::size_t(face[k]);
    x[k] = p[0], y[k] = p[1], z[k] = p[2], w[k] = p[3];
    px[k] = x[k] - X * w[k];
    py[k] = y[k] - Y * w[k];
  }
  const double a[3] = {px[1] * py[2] - py[1] * px[2], px[2] * py[0] - py[2] * px[0],
                       px[0] * py[1] - py[0] * px[1]};
  double a_sum = (a[0] + a[1]) + a[2];
  if (a_sum == 0.0) a_sum = 1.0;  // only a degenerate triangle; it covers nothing
  double b[3];
  for (int k = 0; k < 3; ++k) b[k] = a[k] / a_sum;
  const double wa = (w[0] * a[0] + w[1] * a[1]) + w[2] * a[2];
  const double zw = ((z[0] * a[0] + z[1] * a[1]) + z[2] * a[2]) / (wa == 0.0 ? 1.0 : wa);
  r[0] = float(clamp(b[0], 0.0, 1.0));  // clamped as nvdiffrast does
  r[1] = float(clamp(b[1], 0.0, 1.0));
  r[2] = float(clamp(zw, -1.0, 1.0));
  r[3] = id_to_float(int64_t(prim) + 1);
  if (!db) return;
  // d a_i / dX and d a_i / dY (constant over the triangle: the X Y terms cancel).
  const double da_dx[3] = {y[1] * w[2] - y[2] * w[1], y[2] * w[0] - y[0] * w[2], y[0] * w[1] - y[1] * w[0]};
  const double da_dy[3] = {x[2] * w[1] - x[1] * w[2], x[0] * w[2] - x[2] * w[0], x[1] * w[0] - x[0] * w[1]};
  const double sum_dx = (da_dx[0] + da_dx[1]) + da_dx[2];
  const double sum_dy = (da_dy[0] + da_dy[1]) + da_dy[2];
  const double scale_x = step_x / a_sum, scale_y = step_y / a_sum;
  db[0] = float((da_dx[0] - b[0] * sum_dx) * scale_x);
  db[1] = float((da_dy[0] - b[0] * sum_dy) * scale_y);
  db[2] = float((da_dx[1] - b[1] * sum_dx) * scale_x);
  db[3] = float((da_dy[1] - b[1] * sum_dy) * scale_y);
}

// The pool a call runs on: kept between calls for one thread count (starting and joining workers
// per call cost 0.1 to 4 ms, more than a small image's work), or a pool of the call's own while
// another call holds the kept one (Python threads rasterizing at once). Never destroyed: its
// workers must not be joined while the interpreter exits. (ThreadPool restarts its workers in
// the child of a fork; a cache locked by a thread the fork left behind is never free again, so
// such a child's calls each make their own pool.)
class PoolLease {
 public:
  explicit PoolLease(int threads) : lock_(cache().mutex, std::try_to_lock) {
    Cache& c = cache();
    if (!lock_.owns_lock()) {
      own_ = std::make_unique<ThreadPool>(threads);
      pool_ = own_.get();
      return;
    }
    if (!c.pool || c.threads != threads) {
      c.pool.reset();
      c.pool = std::make_unique<ThreadPool>(threads);
      c.threads = threads;
    }
    pool_ = c.pool.get();
  }
  ThreadPool& pool() { return *pool_; }

 private:
  struct Cache {
    std::mutex mutex;
    int threads = -1;
    std::unique_ptr<ThreadPool> pool;
  };
  static Cache& cache() {
    static Cache* c = new Cache;
    return *c;
  }
  std::unique_lock<std::mutex> lock_;
  std::unique_ptr<ThreadPool> own_;
  ThreadPool* pool_ = nullptr;
};

void check(const ClipRasterInput& in) {
  auto fail = [](const std::string& what) { throw std::invalid_argument(what); };
  if (in.width < 1 || in.width > kMaxImageSide || in.height < 1 || in.height > kMaxImageSide)
    fail("width and height must be in [1, " + std::to_string(kMaxImageSide) + "]");
  if (in.images < 0 || in.num_vertices < 0 || in.num_triangles < 0 || in.num_triangles > 0x7fffffff)
    fail("negative sizes, or over 2^31 - 1 triangles");
  if (in.pos_images != 1 && in.pos_images != in.images)
    fail("pos: one set of positions, or one per image");
  for (int64_t k = 0; k < in.images; ++k) {
    const int64_t first = in.ranges[2 * k], count = in.ranges[2 * k + 1];
    if (first < 0 || count < 0 || first > in.num_triangles - count)
      fail("ranges[" + std::to_string(k) + "] reaches outside tri");
  }
  for (int64_t i = 0; i < 3 * in.num_triangles; ++i)
    if (in.tri[i] < 0 || in.tri[i] >= in.num_vertices)
      fail("tri[" + std::to_string(i / 3) + "] indexes a vertex outside pos");
}

}  // namespace

void rasterize_clip(const ClipRasterInput& in, float* rast, float* rast_db, int threads, Isa isa) {
  check(in);
  PoolLease lease(threads);
  ThreadPool& pool = lease.pool();
  const Viewport viewport(in.width, in.height);
  CameraParams band_camera;  // the guard band's planes; near and far bound z/w + 2 (not read)
  band_camera.near = kDepthOffset - 1.5;
  band_camera.far = kDepthOffset + 1.5;
  const ClipSpacePlanes planes{ClipPlanes(band_camera, in.width, in.height)};
  DrawTransform identity;  // setup reads only `mirrored` (false: the winding as given)
  SetupParams params{};
  params.transform = &identity;
  params.draw = 0;
  params.orthographic = true;
  params.cull = Cull::None;
  params.planes = nullptr;
  params.viewport = viewport;
  params.isa = isa;
  const RasterizeFn kernel = select_rasterize(isa, /*want_coverage=*/false, /*scanline=*/false);
  std::vector<std::unique_ptr<TileScratch>> scratch(std::size_t(pool.size()));
  std::vector<SetupChunk> chunks;
  std::vector<ProjectedVertex> vertices(std::size_t(in.num_vertices));
  const std::size_t pixels = std::size_t(in.width) * std::size_t(in.height);
  const double step_x = 2.0 / in.width, step_y = 2.0 / in.height;
  const std::size_t num_vertices = std::size_t(in.num_vertices);
  int64_t projected = -1;  // which set of positions `vertices` holds

  for (int64_t image = 0; image < in.images; ++image) {
    const int64_t source = in.pos_images == 1 ? 0 : image;
    const float* pos = in.pos + std::size_t(source) * num_vertices * 4;
    const std::size_t first = std::size_t(in.ranges[2 * image]);
    const std::size_t count = std::size_t(in.ranges[2 * image + 1]);
    float* const out = rast + std::size_t(image) * pixels * 4;
    float* const out_db = rast_db ? rast_db + std::size_t(image) * pixels * 4 : nullptr;
    if (count == 0) {
      std::fill(out, out + pixels * 4, 0.0f);
      if (out_db) std::fill(out_db, out_db + pixels * 4, 0.0f);
      continue;
    }
    if (source != projected) {
      const std::size_t blocks = (num_vertices + kVertexBlock - 1) / kVertexBlock;
      pool.parallel_for(blocks, [&](std::size_t b, int) {
        const std::size_t end = std::min(num_vertices, (b + 1) * kVertexBlock);
        for (std::size_t i = b * kVertexBlock; i < end; ++i)
          project_vertex(pos + 4 * i, planes, viewport, vertices[i]);
      });
      projected = source;
    }
    const std::size_t per_chunk = chunk_faces(count);
    const std::size_t num_chunks = (count + per_chunk - 1) / per_chunk;
    if (chunks.size() < num_chunks) chunks.resize(num_chunks);
    pool.parallel_for(num_chunks, [&](std::size_t c, int) {
      const std::size_t begin = first + c * per_chunk;
      setup_clip_chunk(pos, in.tri, vertices.data(), planes, params, begin,
                       std::min(first + count, begin + per_chunk), chunks[c]);
    });
    pool.parallel_for(std::size_t(viewport.num_tiles()), [&](std::size_t tile, int worker) {
      if (!scratch[std::size_t(worker)]) scratch[std::size_t(worker)].reset(new TileScratch);
      TileScratch& s = *scratch[std::size_t(worker)];
      s.tie = kTieFactorOrthographic;
      rasterize_tile(kernel, viewport, int(tile), chunks, num_chunks, false, s);
      const TileRect rect = tile_rect(viewport, int(tile));
      for (int y = rect.y0; y < rect.y1; ++y) {
        const int row = in.height - 1 - y;  // nvdiffrast's row 0 is the bottom
        const double Y = (2.0 * row + 1.0) / in.height - 1.0;
        const std::size_t at = (std::size_t(row) * std::size_t(in.width) + std::size_t(rect.x0)) * 4;
        float* r = out + at;
        float* d = out_db ? out_db + at : nullptr;
        const uint32_t* visible = s.visible + (y - rect.y0) * kTileSizePx;
        for (int x = rect.x0; x < rect.x1; ++x, r += 4, d = d ? d + 4 : nullptr) {
          const uint32_t v = visible[x - rect.x0];
          if (v == kNoTriangle) {
            std::fill(r, r + 4, 0.0f);
            if (d) std::fill(d, d + 4, 0.0f);
            continue;
          }
          const uint32_t prim = s.triangles[v].tri->prim;
          const double X = (2.0 * x + 1.0) / in.width - 1.0;
          shade_pixel(pos, in.tri + 3 * std::size_t(prim), prim, X, Y, step_x, step_y, r, d);
        }
      }
    });
  }
}

}  // namespace sr
