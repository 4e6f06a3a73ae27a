// Lens distortion's exact per-pixel cast and bilinear gathers (distortion.hpp).
#include "distortion.hpp"

#include "transform.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <stdexcept>
#include <thread>
#include <type_traits>

namespace sr {
namespace {

// A ray within this angle (radians, scaled by the ray's length bound) of a face's edge plane
// counts as inside: a ray along an edge shared by two faces hits both (the edge planes of
// neighbours are exact negatives of each other, so no ray passes between them anyway).
constexpr double kEdgeAngle = 1e-12;

// Runs f(i) for i in [0, items) on up to `threads` threads (items handed out in turn); the caller
// is one of them. f's result must not depend on which thread runs an item.
template <typename F>
void parallel(int64_t items, int threads, F&& f) {
  const int n = int(std::clamp<int64_t>(threads, 1, std::max<int64_t>(1, items)));
  if (n == 1) {
    for (int64_t i = 0; i < items; ++i) f(i);
    return;
  }
  std::atomic<int64_t> next{0};
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(n));
  auto run = [&](int k) {
    try {
      for (int64_t i; (i = next.fetch_add(1)) < items;) f(i);
    } catch (...) {
      errors[std::size_t(k)] = std::current_exception();
      next.store(items);
    }
  };
  std::vector<std::thread> workers;
  for (int k = 1; k < n; ++k) workers.emplace_back(run, k);
  run(0);
  for (std::thread& t : workers) t.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

// One face in camera space (relative to the camera centre, OpenCV axes). A ray d = (x', y', 1)
// meets its plane at t d with t = V / (d . n) and barycentric weights b_k = (d . E_k) / (d . n),
// E_k = v_{k+1} x v_{k+2}, n = E_0 + E_1 + E_2, V = v_0 . E_0 (a ray from the shared origin: the
// edge tests are three dot products). F_k = sign(V) E_k: the ray is inside where every
// d . F_k >= 0 (to the edge angle's tolerance).
struct Face {
  dvec3 f[3];
  double tol[3];
  double volume;  // V
  bool front;     // the camera centre sees its counter-clockwise side (a mirroring pose flips it)
};

Face make_face(const dvec3& v0, const dvec3& v1, const dvec3& v2, bool mirrored, double angle) {
  Face face;
  const dvec3 e[3] = {glm::cross(v1, v2), glm::cross(v2, v0), glm::cross(v0, v1)};
  face.volume = glm::dot(v0, e[0]);
  const double sign = face.volume < 0.0 ? -1.0 : 1.0;
  for (int k = 0; k < 3; ++k) {
    face.f[k] = sign * e[k];
    face.tol[k] = -angle * glm::length(e[k]);
  }
  // The camera centre (the origin) is on the side n points to where -v0 . n > 0, i.e. V < 0.
  face.front = (face.volume < 0.0) != mirrored;
  return face;
}

bool culled(const Face& face, Cull cull) {
  return (cull == Cull::Back && !face.front) || (cull == Cull::Front && face.front);
}

// d . F_k for d = (x, y, 1): the three edge values, and whether the ray is inside.
inline bool inside(const Face& face, double x, double y, double e[3]) {
  for (int k = 0; k < 3; ++k) e[k] = face.f[k].x * x + face.f[k].y * y + face.f[k].z;
  return e[0] >= face.tol[0] && e[1] >= face.tol[1] && e[2] >= face.tol[2];
}

struct Draw3 {  // a CastDraw's derived values
  dmat3 to_camera{1.0};  // model -> camera axes (linear part)
  dvec3 offset{0.0};     // model origin in camera space
  dmat3 normal_to_world{1.0};
  bool mirrored = false;
  int64_t first = 0;     // its first face's global index
};

struct Box {
  int32_t x0 = 1, x1 = 0, y0 = 1, y1 = 0;  // inclusive cell ranges; x0 > x1: not cast
};

// A ray's nearest hit so far (16 bytes: the cast's random access is its cost).
struct Best {
  double t = std::numeric_limits<double>::infinity();
  int32_t draw = -1, face = -1;
};

// The box, in grid cells, of the part of the face with depth in [near, far] as seen on z = 1;
// false if there is none or it misses the grid.
bool face_box(const dvec3 v[3], const RayGrid& grid, double near, double far, Box& box) {
  double zmin = std::min({v[0].z, v[1].z, v[2].z}), zmax = std::max({v[0].z, v[1].z, v[2].z});
  if (!(zmax >= near && zmin <= far)) return false;  // NaN too
  double x_lo = std::numeric_limits<double>::infinity(), x_hi = -x_lo, y_lo = x_lo, y_hi = -x_lo;
  auto add = [&](const dvec3& p) {
    const double x = p.x / p.z, y = p.y / p.z;
    x_lo = std::min(x_lo, x), x_hi = std::max(x_hi, x), y_lo = std::min(y_lo, y), y_hi = std::max(y_hi, y);
  };
  if (zmin >= near && zmax <= far) {
    for (int k = 0; k < 3; ++k) add(v[k]);
  } else {  // clip the polygon to near <= z <= far (Sutherland-Hodgman), then its corners
    dvec3 a[5], b[5];
    int na = 3, nb = 0;
    std::copy(v, v + 3, a);
    for (int plane = 0; plane < 2; ++plane) {
      const double limit = plane == 0 ? near : far, side = plane == 0 ? 1.0 : -1.0;
      nb = 0;
      for (int i = 0; i < na; ++i) {
        const dvec3& p = a[i];
        const dvec3& q = a[(i + 1) % na];
        const double dp = side * (p.z - limit), dq = side * (q.z - limit);
        if (dp >= 0.0) b[nb++] = p;
        if ((dp < 0.0) != (dq < 0.0) && nb < 5) {
          dvec3 r = p + (q - p) * (dp / (dp - dq));
          r.z = limit;
          b[nb++] = r;
        }
      }
      std::copy(b, b + nb, a);
      na = nb;
      if (na == 0) return false;
    }
    for (int i = 0; i < na; ++i) add(a[i]);
  }
  // A margin for rounding and the edge tolerance (1e-12 rad), far below a cell.
  const double pad_x = 1e-9 * (1.0 + std::fabs(x_lo) + std::fabs(x_hi));
  const double pad_y = 1e-9 * (1.0 + std::fabs(y_lo) + std::fabs(y_hi));
  const double nx = double(grid.nx), ny = double(grid.ny);
  // Cells, clamped in double before any conversion (a huge or NaN coordinate stays defined).
  auto cell = [](double c, double n) { return std::isnan(c) ? -1.0 : std::clamp(std::floor(c), -1.0, n); };
  const double cx0 = cell((x_lo - pad_x - grid.x0) * grid.inv_cell_x, nx);
  const double cx1 = cell((x_hi + pad_x - grid.x0) * grid.inv_cell_x, nx);
  const double cy0 = cell((y_lo - pad_y - grid.y0) * grid.inv_cell_y, ny);
  const double cy1 = cell((y_hi + pad_y - grid.y0) * grid.inv_cell_y, ny);
  if (std::isnan(x_lo + x_hi + y_lo + y_hi) || cx1 < 0.0 || cy1 < 0.0 || cx0 >= nx || cy0 >= ny) return false;
  box.x0 = int32_t(std::max(cx0, 0.0));
  box.x1 = int32_t(std::min(cx1, nx - 1.0));
  box.y0 = int32_t(std::max(cy0, 0.0));
  box.y1 = int32_t(std::min(cy1, ny - 1.0));
  return true;
}

dvec3 unit_d(const dvec3& v) {
  const double l = glm::length(v);
  return l > 0.0 && std::isfinite(l) ? v / l : dvec3(0.0);
}

struct Candidate {
  int32_t draw, face;
  Box box;
};

}  // namespace

void cast_distorted(const RayGrid& grid, const std::vector<CastDraw>& draws, const CastCamera& camera,
                    const CastView& view, const CastOutputs& out, int threads) {
  const dmat3 to_camera = glm::inverse(camera.camera_to_world);
  // The rays' length bound, for the edge tolerance (|d| = sqrt(x'^2 + y'^2 + 1)).
  double r2_max = 0.0;
  for (const double c : {grid.x0, grid.x0 + double(grid.nx) / grid.inv_cell_x})
    for (const double r : {grid.y0, grid.y0 + double(grid.ny) / grid.inv_cell_y}) r2_max = std::max(r2_max, c * c + r * r);
  const double angle = kEdgeAngle * std::sqrt(1.0 + r2_max);

  // Per draw: model -> camera space, the normal matrix and the mirror flag (the pipeline's).
  std::vector<Draw3> d3(draws.size());
  int64_t faces = 0;
  bool any_masked = false;
  for (std::size_t d = 0; d < draws.size(); ++d) {
    const DrawTransform xf = make_draw_transform(draws[d].model, CameraParams{});
    d3[d].to_camera = to_camera * dmat3(draws[d].model);
    d3[d].offset = to_camera * (dvec3(draws[d].model[3]) - camera.centre);
    d3[d].normal_to_world = xf.normal_to_world;
    d3[d].mirrored = xf.mirrored;
    d3[d].first = faces;
    faces += int64_t(draws[d].mesh->faces.size());
    any_masked |= draws[d].alpha == AlphaKind::Masked;
  }

  // 1. Every vertex in camera space, in double (blocks of 16384 vertices).
  constexpr int64_t kBlock = 16384;
  std::vector<std::vector<dvec3>> verts(draws.size());
  std::vector<std::pair<std::size_t, int64_t>> blocks;
  for (std::size_t d = 0; d < draws.size(); ++d) {
    if (draws[d].alpha == AlphaKind::Invisible) continue;
    verts[d].resize(draws[d].mesh->positions.size());
    for (int64_t b = 0; b < int64_t(verts[d].size()); b += kBlock) blocks.emplace_back(d, b);
  }
  parallel(int64_t(blocks.size()), threads, [&](int64_t i) {
    const auto [d, begin] = blocks[std::size_t(i)];
    const int64_t end = std::min<int64_t>(begin + kBlock, int64_t(verts[d].size()));
    const vec3* p = draws[d].mesh->positions.data();
    for (int64_t k = begin; k < end; ++k) verts[d][std::size_t(k)] = d3[d].to_camera * dvec3(p[k]) + d3[d].offset;
  });

  // 2. Every opaque face's box in the ray grid (culled, behind, beyond or outside: none).
  std::vector<Box> boxes(static_cast<std::size_t>(faces));
  blocks.clear();
  for (std::size_t d = 0; d < draws.size(); ++d)
    if (draws[d].alpha == AlphaKind::Opaque)
      for (int64_t b = 0; b < int64_t(draws[d].mesh->faces.size()); b += kBlock) blocks.emplace_back(d, b);
  parallel(int64_t(blocks.size()), threads, [&](int64_t i) {
    const auto [d, begin] = blocks[std::size_t(i)];
    const MeshData& mesh = *draws[d].mesh;
    const int64_t end = std::min<int64_t>(begin + kBlock, int64_t(mesh.faces.size()));
    const dvec3* vs = verts[d].data();
    for (int64_t f = begin; f < end; ++f) {
      const ivec3 idx = mesh.faces[std::size_t(f)];
      const dvec3 v[3] = {vs[idx[0]], vs[idx[1]], vs[idx[2]]};
      Box& box = boxes[std::size_t(d3[d].first + f)];
      const Face face = make_face(v[0], v[1], v[2], d3[d].mirrored, angle);
      if (face.volume == 0.0 || !std::isfinite(face.volume) || culled(face, draws[d].cull) ||
          !face_box(v, grid, camera.near, camera.far, box))
        box = Box{};
    }
  });

  // 3. Bands of cell rows, each owning its rays: every face whose box reaches the band, sorted
  // by 16 x 16-cell tile of its box's corner (counting sort, stable: draw and face order within a
  // tile), so that consecutive faces read neighbouring rays. The result does not depend on this
  // order: a ray keeps its nearest hit, ties to the first face in draw and face order.
  constexpr int kTileShift = 4;
  const int64_t tiles_x = (grid.nx >> kTileShift) + 1, tiles = tiles_x * ((grid.ny >> kTileShift) + 1);
  std::vector<int64_t> tile_start(static_cast<std::size_t>(tiles + 1), 0);
  int64_t n_candidates = 0;
  for (const Box& box : boxes)
    if (box.x0 <= box.x1) ++tile_start[std::size_t((box.y0 >> kTileShift) * tiles_x + (box.x0 >> kTileShift) + 1)], ++n_candidates;
  for (int64_t k = 0; k < tiles; ++k) tile_start[std::size_t(k + 1)] += tile_start[std::size_t(k)];
  std::vector<Candidate> sorted(static_cast<std::size_t>(n_candidates));
  for (std::size_t d = 0; d < draws.size(); ++d) {
    if (draws[d].alpha != AlphaKind::Opaque) continue;
    const int64_t m = int64_t(draws[d].mesh->faces.size());
    for (int64_t f = 0; f < m; ++f) {
      const Box& box = boxes[std::size_t(d3[d].first + f)];
      if (box.x0 > box.x1) continue;
      int64_t& at = tile_start[std::size_t((box.y0 >> kTileShift) * tiles_x + (box.x0 >> kTileShift))];
      sorted[std::size_t(at++)] = {int32_t(d), int32_t(f), box};
    }
  }
  const int64_t n_bands = threads <= 1 ? 1 : std::min<int64_t>(grid.ny, 4 * int64_t(threads));
  std::vector<std::vector<Candidate>> bands(std::size_t(std::max<int64_t>(n_bands, 1)));
  auto band_of = [&](int64_t row) { return row * n_bands / std::max<int64_t>(grid.ny, 1); };
  for (const Candidate& c : sorted)
    for (int64_t b = band_of(c.box.y0), last = band_of(c.box.y1); b <= last; ++b) bands[std::size_t(b)].push_back(c);
  std::vector<Best> best(static_cast<std::size_t>(grid.count));
  std::vector<uint32_t> hits(out.coverage ? std::size_t(grid.count) : 0, 0);  // faces hit (coverage)
  parallel(n_bands, threads, [&](int64_t b) {
    const int64_t row0 = (b * grid.ny + n_bands - 1) / n_bands;  // rows r with band_of(r) == b
    const int64_t row1 = ((b + 1) * grid.ny + n_bands - 1) / n_bands;
    for (const Candidate& c : bands[std::size_t(b)]) {
      const ivec3 idx = draws[std::size_t(c.draw)].mesh->faces[std::size_t(c.face)];
      const dvec3* vs = verts[std::size_t(c.draw)].data();
      const Face face = make_face(vs[idx[0]], vs[idx[1]], vs[idx[2]], false, angle);
      const double volume = std::fabs(face.volume);
      const int64_t y0 = std::max<int64_t>(c.box.y0, row0), y1 = std::min<int64_t>(c.box.y1, row1 - 1);
      for (int64_t y = y0; y <= y1; ++y) {
        const int64_t s0 = grid.cell_start[y * grid.nx + c.box.x0], s1 = grid.cell_start[y * grid.nx + c.box.x1 + 1];
        for (int64_t s = s0; s < s1; ++s) {
          double e[3];
          if (!inside(face, grid.xy[2 * s], grid.xy[2 * s + 1], e)) continue;
          const double t = volume / (e[0] + e[1] + e[2]);
          if (!(t >= camera.near && t <= camera.far)) continue;
          Best& r = best[std::size_t(s)];
          if (out.coverage) ++hits[std::size_t(s)];
          if (t < r.t || (t == r.t && (c.draw < r.draw || (c.draw == r.draw && c.face < r.face)))) {
            r.t = t;
            r.draw = c.draw;
            r.face = c.face;
          }
        }
      }
    }
  });
  // 4. Per pixel: masked draws through the view's samples, then every output from the hit.
  const int64_t w = view.rays ? view.rays->view_width : 0;
  auto view_face = [&](int64_t s, int32_t& d) -> int32_t {
    const int32_t tri = view.triangle_id[s];
    if (tri < 0) return -1;
    d = view.instance[s];
    if (d < 0 || std::size_t(d) >= draws.size() || std::size_t(tri) >= draws[std::size_t(d)].mesh->faces.size())
      throw std::invalid_argument("cast_distorted: a view id names no instance or face");
    return tri;
  };
  // Blocks of rays in cell order (reading their results in order), then blocks of pixels for the
  // ones without a ray (background).
  constexpr int64_t kPixels = 4096;
  const int64_t ray_blocks = (grid.count + kPixels - 1) / kPixels;
  parallel(ray_blocks + (grid.n + kPixels - 1) / kPixels, threads, [&](int64_t blk) {
    const bool rays_block = blk < ray_blocks;
    const int64_t begin = (rays_block ? blk : blk - ray_blocks) * kPixels;
    const int64_t end = std::min(rays_block ? grid.count : grid.n, begin + kPixels);
    for (int64_t i = begin; i < end; ++i) {
      if (!rays_block && grid.slot[i] >= 0) continue;
      const int64_t s = rays_block ? i : -1, p = rays_block ? grid.pixel[i] : i;
      Best r = s >= 0 ? best[std::size_t(s)] : Best{};
      uint32_t count = s >= 0 && out.coverage ? hits[std::size_t(s)] : 0;
      double hit_e[3] = {0.0, 0.0, 0.0};  // the hit's edge values (a masked face's, found here)
      bool front = false, have_e = false;
      const double x = s >= 0 ? grid.xy[2 * s] : 0.0, y = s >= 0 ? grid.xy[2 * s + 1] : 0.0;
      int64_t around[5] = {-1, -1, -1, -1, -1};
      if (view.rays && s >= 0) {
        const int64_t c = view.rays->corner[p];
        around[0] = view.rays->nearest[p], around[1] = c, around[2] = c + 1, around[3] = c + w, around[4] = c + w + 1;
      }
      if (any_masked && view.rays && s >= 0) {
        for (int k = 0; k < 5; ++k) {
          int32_t d = -1;
          const int32_t f = view_face(around[k], d);
          if (f < 0 || draws[std::size_t(d)].alpha != AlphaKind::Masked) continue;
          bool seen = false;  // each face once
          for (int j = 0; j < k; ++j) seen |= view.triangle_id[around[j]] == f && view.instance[around[j]] == d;
          if (seen) continue;
          const ivec3 idx = draws[std::size_t(d)].mesh->faces[std::size_t(f)];
          const dvec3* vs = verts[std::size_t(d)].data();
          const Face face = make_face(vs[idx[0]], vs[idx[1]], vs[idx[2]], d3[std::size_t(d)].mirrored, angle);
          double e[3];
          if (face.volume == 0.0 || culled(face, draws[std::size_t(d)].cull) || !inside(face, x, y, e)) continue;
          const double th = std::fabs(face.volume) / (e[0] + e[1] + e[2]);
          if (!(th >= camera.near && th <= camera.far)) continue;
          ++count;
          if (r.draw < 0 || th < r.t || (th == r.t && (d < r.draw || (d == r.draw && f < r.face)))) {
            r.t = th;
            r.draw = d;
            r.face = f;
            std::copy(e, e + 3, hit_e);
            front = face.front, have_e = true;
          }
        }
      }
      const int32_t draw = r.draw, face_id = r.face;
      const double t = r.t;
      const bool hit = draw >= 0;
      if (out.triangle_id) out.triangle_id[p] = hit ? face_id : -1;
      if (out.instance) out.instance[p] = hit ? draw : -1;
      if (out.mask) out.mask[p] = hit;
      if (out.alpha) out.alpha[p] = hit ? 1.0f : 0.0f;
      if (out.coverage) out.coverage[p] = count;
      if (out.sample) {
        int64_t chosen = around[0];
        for (int k = 0; s >= 0 && k < 5; ++k) {
          int32_t d = -1;
          if (view_face(around[k], d) == face_id && hit && d == draw) {  // (every id checked)
            chosen = around[k];
            break;
          }
        }
        out.sample[p] = std::max<int64_t>(chosen, 0);
      }
      if (!hit) {
        if (out.depth) out.depth[p] = 0.0f;
        if (out.ray_depth) out.ray_depth[p] = 0.0f;
        if (out.position) std::fill(out.position + 3 * p, out.position + 3 * p + 3, 0.0f);
        if (out.barycentric) std::fill(out.barycentric + 3 * p, out.barycentric + 3 * p + 3, 0.0f);
        if (out.uv) std::fill(out.uv + 2 * p, out.uv + 2 * p + 2, 0.0f);
        if (out.normal) std::fill(out.normal + 3 * p, out.normal + 3 * p + 3, 0.0f);
        continue;
      }
      const CastDraw& cd = draws[std::size_t(draw)];
      const Draw3& dd = d3[std::size_t(draw)];
      const ivec3 idx = cd.mesh->faces[std::size_t(face_id)];
      if (!have_e) {  // the same values the cast tested
        const dvec3* vs = verts[std::size_t(draw)].data();
        const Face face = make_face(vs[idx[0]], vs[idx[1]], vs[idx[2]], dd.mirrored, angle);
        inside(face, x, y, hit_e);
        front = face.front;
      }
      double b[3], sum = 0.0;
      for (int k = 0; k < 3; ++k) sum += (b[k] = std::max(hit_e[k], 0.0));  // within the tolerance: 0
      for (double& v : b) v = sum > 0.0 ? v / sum : 1.0 / 3.0;
      const dvec3 point = t * (camera.camera_to_world * dvec3(x, y, 1.0));  // relative to the centre
      if (out.depth) out.depth[p] = float(t);
      if (out.ray_depth) out.ray_depth[p] = float(glm::length(point));
      if (out.position)
        for (int k = 0; k < 3; ++k) out.position[3 * p + k] = float(point[k] + camera.centre[k]);
      if (out.barycentric)
        for (int k = 0; k < 3; ++k) out.barycentric[3 * p + k] = float(b[k]);
      if (out.uv) {
        glm::dvec2 uv(0.0);
        if (!cd.mesh->uvs.empty())
          for (int k = 0; k < 3; ++k) uv += b[k] * glm::dvec2(cd.mesh->uvs[std::size_t(idx[k])]);
        out.uv[2 * p] = float(uv.x);
        out.uv[2 * p + 1] = float(uv.y);
      }
      if (out.normal) {
        // The pipeline's interpolated normal: unit world vertex normals (the face normal for a
        // mesh without normals, or in place of a zero one), weighted, unit, of the side seen.
        const vec3* pos = cd.mesh->positions.data();
        const dvec3 p0(pos[idx[0]]);
        const dvec3 flat = unit_d(dd.normal_to_world * glm::cross(dvec3(pos[idx[1]]) - p0, dvec3(pos[idx[2]]) - p0));
        dvec3 n(0.0);
        for (int k = 0; k < 3; ++k) {
          dvec3 nk = cd.mesh->normals.empty() ? flat : unit_d(dd.normal_to_world * dvec3(cd.mesh->normals[std::size_t(idx[k])]));
          if (nk == dvec3(0.0)) nk = flat;
          n += b[k] * nk;
        }
        n = unit_d(n);
        if (!front) n = -n;
        for (int k = 0; k < 3; ++k) out.normal[3 * p + k] = float(n[k]);
      }
    }
  });
}

namespace {

template <typename T>
void gather(const DistortionRays& rays, const float* weights, const T* src, int channels, T* out) {
  const int64_t n = rays.n, w = rays.view_width;
  for (int64_t p = 0; p < n; ++p) {
    if (!rays.valid[p]) continue;
    const float w0 = weights[p], w1 = weights[n + p], w2 = weights[2 * n + p], w3 = weights[3 * n + p];
    const int64_t c = rays.corner[p];
    const T* s0 = src + c * channels;
    const T* s1 = src + (c + 1) * channels;
    const T* s2 = src + (c + w) * channels;
    const T* s3 = src + (c + w + 1) * channels;
    for (int k = 0; k < channels; ++k) {
      const float v = (float(s0[k]) * w0 + float(s1[k]) * w1) + (float(s2[k]) * w2 + float(s3[k]) * w3);
      if constexpr (std::is_same_v<T, uint8_t>)
        out[p * channels + k] = uint8_t(std::clamp(std::floor(v + 0.5f), 0.0f, 255.0f));
      else
        out[p * channels + k] = v;
    }
  }
}

}  // namespace

void bilinear_gather(const DistortionRays& rays, const float* weights, const uint8_t* src, int channels,
                     uint8_t* out) {
  gather(rays, weights, src, channels, out);
}

void bilinear_gather(const DistortionRays& rays, const float* weights, const float* src, int channels,
                     float* out) {
  gather(rays, weights, src, channels, out);
}

}  // namespace sr
