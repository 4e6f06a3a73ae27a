// Exact shadows: the occluders' bounding volume hierarchy and the shadow ray (shadow.hpp).
#include "shadow.hpp"

#include "pipeline.hpp"
#include "simd.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sr {

namespace {

constexpr int kLeafTriangles = 4;   // a leaf holds at most this many, unless they cannot be split
constexpr int kBins = 16;           // surface-area heuristic: candidate splits per axis
constexpr int kMaxDepth = 120;      // deeper ranges become leaves (the traversal's stack bound)
// 2^-19: a triangle whose plane passes within this fraction of its coordinates' magnitude of the
// shaded point does not shadow it (shadow.hpp).
constexpr double kOnSurface = 1.0 / 524288.0;
// The slab test's exit distance is widened by 1 + 2 gamma(3) (PBRT's robust ray-box test): no ray
// that meets a triangle misses its box by rounding.
constexpr double kSlabPad = 1.0 + 2.0 * (3.0 * 0x1p-53 / (1.0 - 3.0 * 0x1p-53));

double max_abs(const dvec3& v) {
  return std::max(std::fabs(v.x), std::max(std::fabs(v.y), std::fabs(v.z)));
}

double half_area(const dvec3& lo, const dvec3& hi) {
  const dvec3 e = hi - lo;
  return e.x * e.y + e.y * e.z + e.z * e.x;
}

struct Box {
  dvec3 lo{std::numeric_limits<double>::infinity()};
  dvec3 hi{-std::numeric_limits<double>::infinity()};
  void grow(const dvec3& p) { lo = glm::min(lo, p); hi = glm::max(hi, p); }
  void grow(const Box& b) { lo = glm::min(lo, b.lo); hi = glm::max(hi, b.hi); }
  double area() const { return lo.x <= hi.x ? half_area(lo, hi) : 0.0; }
};

}  // namespace

void ShadowScene::build(const std::vector<Draw>& draws, const std::vector<uint8_t>& casts) {
  std::vector<std::pair<std::shared_ptr<const MeshData>, dmat4>> from;
  for (std::size_t d = 0; d < draws.size(); ++d)
    if (casts[d]) from.emplace_back(draws[d].mesh, draws[d].model);
  if (!from.empty() && from == built_from_) return;  // (the same occluders: kept)
  built_from_ = std::move(from);
  tris_.clear();
  nodes_.clear();
  grids_.clear();
  std::vector<Box> boxes;
  std::vector<dvec3> centres;
  for (std::size_t d = 0; d < draws.size(); ++d) {
    if (!casts[d]) continue;
    const MeshData& mesh = *draws[d].mesh;
    const dmat4& model = draws[d].model;
    for (const ivec3& f : mesh.faces) {
      dvec3 v[3];
      for (int k = 0; k < 3; ++k) v[k] = dvec3(model * dvec4(dvec3(mesh.positions[f[k]]), 1.0));
      const dvec3 e1 = v[1] - v[0], e2 = v[2] - v[0];
      const dvec3 n = glm::cross(e1, e2);
      if (!(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z)) || n == dvec3(0.0))
        continue;
      tris_.push_back({v[0], e1, e2, n, glm::dot(n, n),
                       std::max(max_abs(v[0]), std::max(max_abs(v[1]), max_abs(v[2])))});
      Box b;
      for (int k = 0; k < 3; ++k) b.grow(v[k]);
      boxes.push_back(b);
      centres.push_back((b.lo + b.hi) * 0.5);
    }
  }
  if (tris_.empty()) return;
  std::vector<uint32_t> order(tris_.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = uint32_t(i);

  // Depth first, so that a node's first child follows it; `parent` gets its second child's index.
  struct Work { uint32_t begin, end, parent; int depth; };
  std::vector<Work> stack{{0, uint32_t(order.size()), UINT32_MAX, 0}};
  nodes_.reserve(2 * tris_.size() / kLeafTriangles + 1);
  while (!stack.empty()) {
    const Work w = stack.back();
    stack.pop_back();
    const uint32_t self = uint32_t(nodes_.size());
    if (w.parent != UINT32_MAX) nodes_[w.parent].index = self;
    Box box, centre_box;
    for (uint32_t i = w.begin; i < w.end; ++i) {
      box.grow(boxes[order[i]]);
      centre_box.grow(centres[order[i]]);
    }
    nodes_.push_back({{{box.lo.x, box.lo.y, box.lo.z}, {box.hi.x, box.hi.y, box.hi.z}},
                      w.begin, w.end - w.begin});
    const uint32_t count = w.end - w.begin;
    if (count <= kLeafTriangles || w.depth >= kMaxDepth) continue;
    // The surface-area heuristic over kBins bins of the centres along each axis (all three: a
    // floor's large triangles beside a small object separate only along the floor's normal).
    const dvec3 extent = centre_box.hi - centre_box.lo;
    double best = std::numeric_limits<double>::infinity();
    int best_axis = -1, split = -1;
    for (int axis = 0; axis < 3; ++axis) {
      if (!(extent[axis] > 0.0)) continue;
      const double lo = centre_box.lo[axis], scale = kBins / extent[axis];
      Box bin_box[kBins];
      uint32_t bin_count[kBins] = {};
      for (uint32_t i = w.begin; i < w.end; ++i) {
        const uint32_t t = order[i];
        const int b = std::min(kBins - 1, int((centres[t][axis] - lo) * scale));
        bin_box[b].grow(boxes[t]);
        ++bin_count[b];
      }
      // Cost of splitting before bin b: area(left) * n(left) + area(right) * n(right).
      double right_area[kBins];
      uint32_t right_count[kBins];
      Box acc;
      uint32_t n = 0;
      for (int b = kBins - 1; b > 0; --b) {
        acc.grow(bin_box[b]);
        n += bin_count[b];
        right_area[b] = acc.area();
        right_count[b] = n;
      }
      Box left;
      uint32_t left_n = 0;
      for (int b = 1; b < kBins; ++b) {
        left.grow(bin_box[b - 1]);
        left_n += bin_count[b - 1];
        if (left_n == 0 || right_count[b] == 0) continue;
        const double cost = left.area() * left_n + right_area[b] * right_count[b];
        if (cost < best) { best = cost; best_axis = axis; split = b; }
      }
    }
    int axis = best_axis;
    if (axis < 0) {  // (no split separates the bins: the widest axis's median, or one leaf)
      axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : extent.y >= extent.z ? 1 : 2;
      if (!(extent[axis] > 0.0)) continue;  // every centre the same: one leaf
    }
    uint32_t middle;
    if (split > 0) {
      const double lo = centre_box.lo[axis], scale = kBins / extent[axis];
      middle = uint32_t(std::partition(order.begin() + w.begin, order.begin() + w.end,
                                       [&](uint32_t t) {
                                         return std::min(kBins - 1, int((centres[t][axis] - lo) * scale)) < split;
                                       }) -
                        order.begin());
    } else {
      middle = w.begin + count / 2;
      std::nth_element(order.begin() + w.begin, order.begin() + middle, order.begin() + w.end,
                       [&](uint32_t a, uint32_t b) { return centres[a][axis] < centres[b][axis]; });
    }
    nodes_[self].count = 0;
    stack.push_back({middle, w.end, self, w.depth + 1});   // second child (index patched)
    stack.push_back({w.begin, middle, UINT32_MAX, w.depth + 1});  // first child: self + 1
  }
  std::vector<Tri> sorted(tris_.size());
  for (std::size_t i = 0; i < order.size(); ++i) sorted[i] = tris_[order[i]];
  tris_.swap(sorted);
}

__attribute__((always_inline)) inline bool ShadowScene::hits(const Tri& tri, const dvec3& o,
                                                              const dvec3& d, double t_max) const {
  // The plane first (two dot products): the ray meets it at t = -(n . (o - a)) / (n . d), which
  // must lie in (0, t_max) (no division: signs and magnitudes).
  const dvec3 tvec = o - tri.a;
  const double along = glm::dot(tri.n, tvec), dn = glm::dot(tri.n, d);
  if (!(along * dn < 0.0)) return false;
  if (t_max < std::numeric_limits<double>::infinity() && !(std::fabs(along) < t_max * std::fabs(dn)))
    return false;
  // A triangle whose plane passes through the shaded point (within its float32 precision) does
  // not shadow it: |n . (o - a)| / |n| <= eps, squared.
  const double eps = kOnSurface * std::max(tri.scale, max_abs(o));
  if (along * along <= eps * eps * tri.nn) return false;
  // Inside the triangle: Moller-Trumbore's barycentrics, edges included.
  const dvec3 pvec = glm::cross(d, tri.e2);
  const double det = glm::dot(tri.e1, pvec);
  if (det == 0.0 || !std::isfinite(det)) return false;
  const double inv = 1.0 / det;
  const double u = glm::dot(tvec, pvec) * inv;
  if (!(u >= 0.0 && u <= 1.0)) return false;
  const dvec3 qvec = glm::cross(tvec, tri.e1);
  const double v = glm::dot(d, qvec) * inv;
  return v >= 0.0 && u + v <= 1.0;
}

namespace {
constexpr uint32_t kGridCellMax = 64;
// A projected box is padded by this fraction of its coordinates' magnitude: the projection's
// rounding (a few ulps) never drops a triangle the exact test would find.
constexpr double kGridPad = 0x1p-30;
}  // namespace

void ShadowScene::prepare(const std::vector<Light>& lights) {
  if (tris_.empty()) return;
  for (const Light& light : lights) {
    if (light.shadow != ShadowMethod::Exact || light.kind != LightKind::Directional) continue;
    bool have = false;
    for (const DirectionGrid& g : grids_) have |= g.direction == light.direction;
    if (have) continue;
    DirectionGrid grid;
    grid.direction = light.direction;
    build_grid(grid);
    grids_.push_back(std::move(grid));
  }
}

void ShadowScene::build_grid(DirectionGrid& g) const {
  const dvec3 w = glm::normalize(-dvec3(g.direction));
  g.w = w;
  // Any axis across w, then the third.
  const dvec3 helper = std::fabs(w.x) < 0.6 ? dvec3(1, 0, 0) : dvec3(0, 1, 0);
  g.u = glm::normalize(glm::cross(helper, w));
  g.v = glm::cross(w, g.u);
  const std::size_t n = tris_.size();
  std::vector<double> box(4 * n);  // s_lo, t_lo, s_hi, t_hi per triangle
  std::vector<double> top(n);      // the corners' largest w . x, padded
  double lo_s = std::numeric_limits<double>::infinity(), lo_t = lo_s, hi_s = -lo_s, hi_t = -lo_s;
  for (std::size_t i = 0; i < n; ++i) {
    const Tri& t = tris_[i];
    const dvec3 c[3] = {t.a, t.a + t.e1, t.a + t.e2};
    double s_lo = glm::dot(c[0], g.u), s_hi = s_lo, t_lo = glm::dot(c[0], g.v), t_hi = t_lo;
    for (int k = 1; k < 3; ++k) {
      const double s = glm::dot(c[k], g.u), tt = glm::dot(c[k], g.v);
      s_lo = std::min(s_lo, s); s_hi = std::max(s_hi, s);
      t_lo = std::min(t_lo, tt); t_hi = std::max(t_hi, tt);
    }
    const double pad = kGridPad * 4.0 * t.scale;
    top[i] = std::max(glm::dot(c[0], w), std::max(glm::dot(c[1], w), glm::dot(c[2], w))) + pad;
    box[4 * i] = s_lo - pad; box[4 * i + 1] = t_lo - pad;
    box[4 * i + 2] = s_hi + pad; box[4 * i + 3] = t_hi + pad;
    lo_s = std::min(lo_s, box[4 * i]); lo_t = std::min(lo_t, box[4 * i + 1]);
    hi_s = std::max(hi_s, box[4 * i + 2]); hi_t = std::max(hi_t, box[4 * i + 3]);
  }
  // Square cells, eight per triangle (2, 8 and 16 were measured: 8 is as fast as 16 with half
  // the memory), at most 4M cells and 2048 a side.
  const double ws = hi_s - lo_s, wt = hi_t - lo_t;
  const double cells = std::min(4.0e6, std::max(64.0, 8.0 * double(n)));
  double cell = std::sqrt(std::max(ws * wt, 1e-300) / cells);
  if (!(cell > 0.0) || !std::isfinite(cell)) cell = std::max(ws, wt) > 0.0 ? std::max(ws, wt) : 1.0;
  g.nx = std::clamp(int(std::ceil(ws / cell)), 1, 2048);
  g.ny = std::clamp(int(std::ceil(wt / cell)), 1, 2048);
  cell = std::max(ws / g.nx, wt / g.ny);
  if (!(cell > 0.0)) cell = 1.0;
  g.s0 = lo_s;
  g.t0 = lo_t;
  g.inv_cell = 1.0 / cell;
  const auto span = [&](double lo, double hi, double origin, int cells_n, int& a, int& b) {
    a = std::clamp(int(std::floor((lo - origin) * g.inv_cell)), 0, cells_n - 1);
    b = std::clamp(int(std::floor((hi - origin) * g.inv_cell)), 0, cells_n - 1);
  };
  const std::size_t num_cells = std::size_t(g.nx) * std::size_t(g.ny);
  g.start.assign(num_cells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    int x0, x1, y0, y1;
    span(box[4 * i], box[4 * i + 2], g.s0, g.nx, x0, x1);
    span(box[4 * i + 1], box[4 * i + 3], g.t0, g.ny, y0, y1);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) ++g.start[std::size_t(y) * g.nx + x + 1];
  }
  g.crowded.assign(num_cells, 0);
  for (std::size_t c = 0; c < num_cells; ++c) {
    if (g.start[c + 1] > kGridCellMax) { g.crowded[c] = 1; g.start[c + 1] = 0; }
    g.start[c + 1] += g.start[c];
  }
  g.items.resize(g.start[num_cells]);
  g.reach.resize(g.start[num_cells]);
  std::vector<uint32_t> fill(g.start.begin(), g.start.end() - 1);
  for (std::size_t i = 0; i < n; ++i) {  // (in the hierarchy's order: a cell's list likewise)
    int x0, x1, y0, y1;
    span(box[4 * i], box[4 * i + 2], g.s0, g.nx, x0, x1);
    span(box[4 * i + 1], box[4 * i + 3], g.t0, g.ny, y0, y1);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const std::size_t c = std::size_t(y) * g.nx + x;
        if (!g.crowded[c]) g.items[fill[c]++] = uint32_t(i);
      }
  }
  // Each cell's list nearest the light first (ties: the hierarchy's order).
  for (std::size_t c = 0; c < num_cells; ++c) {
    uint32_t* first = g.items.data() + g.start[c];
    uint32_t* last = g.items.data() + g.start[c + 1];
    std::stable_sort(first, last, [&](uint32_t a, uint32_t b) { return top[a] > top[b]; });
    for (uint32_t k = g.start[c]; k < g.start[c + 1]; ++k) g.reach[k] = top[g.items[k]];
  }
}

bool ShadowScene::blocked_in_grid(const DirectionGrid& g, std::size_t c, const dvec3& o,
                                  const dvec3& d) const {
  const double inf = std::numeric_limits<double>::infinity();
  // A triangle reaching no farther toward the light than the point lies behind the ray's start
  // (the ray meets a plane only at t > 0: beyond the point, toward the light), and so do the
  // rest of the list. (The pad covers w . o's rounding too: o's magnitude is the triangles'
  // scale or the on-surface rule's own.)
  const double from = glm::dot(o, g.w) - kGridPad * 4.0 * max_abs(o);
  for (uint32_t k = g.start[c]; k < g.start[c + 1] && g.reach[k] >= from; ++k)
    if (hits(tris_[g.items[k]], o, d, inf)) return true;
  return false;
}

bool ShadowScene::blocked(const Light& light, const dvec3& o) const {
  if (nodes_.empty()) return false;
  dvec3 d;
  double t_max;
  if (light.kind == LightKind::Directional) {
    d = -dvec3(light.direction);
    t_max = std::numeric_limits<double>::infinity();
    for (const DirectionGrid& g : grids_)
      if (g.direction == light.direction) {
        const double s = (glm::dot(o, g.u) - g.s0) * g.inv_cell, t = (glm::dot(o, g.v) - g.t0) * g.inv_cell;
        // Outside the grid (with a cell's margin for rounding): no triangle's projection holds it.
        if (!(s >= -1.0 && t >= -1.0 && s < g.nx + 1.0 && t < g.ny + 1.0)) return false;
        const int x = std::clamp(int(s), 0, g.nx - 1), y = std::clamp(int(t), 0, g.ny - 1);
        const std::size_t c = std::size_t(y) * g.nx + x;
        if (!g.crowded[c]) return blocked_in_grid(g, c, o, d);
        break;  // (a crowded cell: the hierarchy)
      }
  } else {
    d = dvec3(light.position) - o;
    t_max = 1.0;
    if (d == dvec3(0.0)) return false;  // (the light at the point: it lights nothing there)
  }
  const dvec3 inv = 1.0 / d;
  // Per axis, which of a box's corners the ray meets first: the slab test without branches.
  const int near[3] = {inv.x < 0.0, inv.y < 0.0, inv.z < 0.0};
  uint32_t stack[kMaxDepth + 2];
  int top = 0;
  uint32_t node = 0;
  for (;;) {
    const Node& n = nodes_[node];
    double t0 = 0.0, t1 = t_max;
    for (int a = 0; a < 3; ++a) {
      const double enter = (n.bound[near[a]][a] - o[a]) * inv[a];
      const double leave = (n.bound[1 - near[a]][a] - o[a]) * inv[a] * kSlabPad;
      t0 = enter > t0 ? enter : t0;  // (NaN, 0 * inf on a slab's face: the axis does not narrow)
      t1 = leave < t1 ? leave : t1;
    }
    if (t0 <= t1) {
      if (n.count == 0) {
        // Both children: the first now, the second later.
        stack[top++] = n.index;
        node = node + 1;
        continue;
      }
      for (uint32_t i = n.index; i < n.index + n.count; ++i)
        if (hits(tris_[i], o, d, t_max)) return true;
    }
    if (top == 0) return false;
    node = stack[--top];
  }
}

void finish_face(ShadowMapFace& f) {
  f.view_proj = f.proj * f.view;
  const dmat4 to_world = glm::inverse(f.view);
  f.eye = vec3(dvec3(to_world[3]));
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) f.rot[r][c] = float(f.view[c][r]);  // (glm: [column][row])
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) f.proj_rows[r][c] = float(f.proj[c][r]);
  f.texel_scale = float(2.0 / (f.proj[0][0] * f.size));
}

float map_filtered(const ShadowMapFace& f, float sx, float sy, float compare) {
  // floor without a call (the generic target has no rounding instruction): sx, sy lie within a
  // texel of the map (the point is inside the face's image).
  const int xi = int(sx), yi = int(sy);
  const float x0 = float(xi - (sx < float(xi))), y0 = float(yi - (sy < float(yi)));
  const float fx = sx - x0, fy = sy - y0;
  const float wx[4] = {1.0f - fx, 1.0f, 1.0f, fx}, wy[4] = {1.0f - fy, 1.0f, 1.0f, fy};
  const int i0 = int(x0) - 1, j0 = int(y0) - 1;
  float sum = 0.0f;
  if (i0 >= 0 && j0 >= 0 && i0 + 3 < f.size && j0 + 3 < f.size) {
    // A row of four texels as one vector: its passing texels' weights, times the row's.
    using simd::f4;
    using simd::i4;
    const float* row = f.depth.data() + std::size_t(j0) * std::size_t(f.size) + std::size_t(i0);
    const f4 weights = {wx[0], wx[1], wx[2], wx[3]};
    const f4 limit = simd::broadcast<f4>(compare);
    f4 acc = {};
    for (int b = 0; b < 4; ++b, row += f.size) {
      const f4 d = simd::load<f4>(row);
      const i4 pass = (d <= f4{}) | (d >= limit);
      acc += wy[b] * f4(pass & i4(weights));
    }
    sum = (acc[0] + acc[1]) + (acc[2] + acc[3]);
  } else {
    for (int b = 0; b < 4; ++b) {
      float line = 0.0f;
      for (int a = 0; a < 4; ++a) {
        const int i = i0 + a, j = j0 + b;
        const bool outside = i < 0 || j < 0 || i >= f.size || j >= f.size;
        const float d = outside ? 0.0f : f.depth[std::size_t(j) * std::size_t(f.size) + std::size_t(i)];
        line += (d <= 0.0f) | (d >= compare) ? wx[a] : 0.0f;
      }
      sum += wy[b] * line;
    }
  }
  return sum * (1.0f / 9.0f);
}


const float* shadow_lights(const ShadowScene& scene, const Light* lights, int num_lights,
                           const float* x, const float* y, const float* z, const float* nx,
                           const float* ny, const float* nz, bool facing, uint32_t mask) {
  static thread_local std::vector<float> out;
  out.assign(std::size_t(8) * std::size_t(num_lights), 1.0f);
  // The lanes with a finite point; normals that are not finite count as none (zero).
  uint32_t finite = 0;
  alignas(32) float m[3][8] = {};
  for (int i = 0; i < 8; ++i) {
    if (!(mask >> i & 1u) || !(std::isfinite(x[i]) && std::isfinite(y[i]) && std::isfinite(z[i])))
      continue;
    finite |= 1u << i;
    if (std::isfinite(nx[i]) && std::isfinite(ny[i]) && std::isfinite(nz[i])) {
      m[0][i] = nx[i]; m[1][i] = ny[i]; m[2][i] = nz[i];
    }
  }
  if (!finite) return out.data();
  for (int k = 0; k < num_lights; ++k) {
    const Light& light = lights[k];
    if (light.shadow == ShadowMethod::None || (light.shadow == ShadowMethod::Map && !light.map))
      continue;
    float* vis = out.data() + 8 * k;
    // A map: eight lanes at a time, in float. (Lanes facing away from the light get a
    // visibility too: it multiplies nothing.)
    if (light.shadow == ShadowMethod::Map) {
      using simd::f8;
      using simd::load;
      const f8 p[3] = {load<f8>(x), load<f8>(y), load<f8>(z)};
      const f8 n[3] = {load<f8>(m[0]), load<f8>(m[1]), load<f8>(m[2])};
      map_lanes(*light.map, light, p, n, finite, vis);
      continue;
    }
    for (int i = 0; i < 8; ++i) {
      if (!(finite >> i & 1u)) continue;
      const dvec3 p(x[i], y[i], z[i]), n(m[0][i], m[1][i], m[2][i]);
      if (facing) {  // (a lane whose normal faces away gets nothing from the light: no ray)
        const dvec3 l = light.kind == LightKind::Directional ? -dvec3(light.direction)
                                                            : dvec3(light.position) - p;
        const double nl = glm::dot(n, l);  // (n . l < -2^-20 |n| |l|, squared)
        if (nl < 0.0 && nl * nl > 0x1p-40 * glm::dot(n, n) * glm::dot(l, l)) continue;
      }
      if (scene.blocked(light, p)) vis[i] = 0.0f;
    }
  }
  return out.data();
}

}  // namespace sr
