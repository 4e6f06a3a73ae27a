// Vertex stage: every mesh vertex transformed, projected and snapped once, eight at a time.
#include "vertex.hpp"

#include "dispatch.hpp"
#include "lanes.hpp"

#include <cmath>
#include <cstddef>

namespace sr {

namespace {

// Round half away from zero (as lround) by truncation: one instruction instead of a libm call.
inline int32_t round_to_fixed(double scaled) {
  return int32_t(scaled + (scaled >= 0.0 ? 0.5 : -0.5));
}

}  // namespace

// Snaps one vertex. With `snap_outside`, a vertex outside some plane is snapped too (clipping
// output that rounding left a hair outside the plane it was clipped to: the guard band's margin
// keeps it representable). Writes `v` in place: a returned copy would be read back with wider
// loads than it was written with, which stalls store-to-load forwarding.
void project(const vec4& p_clip, float depth_view, const ExactClip& exact,
             const ClipPlanes& planes, const Viewport& viewport, bool orthographic,
             bool snap_outside, ProjectedVertex& v) {
  v = ProjectedVertex{};
  const bool finite = std::isfinite(p_clip.x) && std::isfinite(p_clip.y) &&
                      std::isfinite(p_clip.z) && std::isfinite(p_clip.w) &&
                      std::isfinite(depth_view);
  if (!finite) {
    v.outcode = kInvalidVertex;
    return;
  }
  v.outcode = planes.outcode(p_clip, depth_view);
  if (v.outcode != 0 && !snap_outside) return;
  if (!(p_clip.w > 0.0f) || !(depth_view > 0.0f)) {  // not a projection we can rasterize
    v.outcode = kInvalidVertex;
    return;
  }
  // Double precision: the snapped position must not depend on rounding in the divide.
  const double inv_w = 1.0 / double(p_clip.w);
  const double x_window = (double(p_clip.x) * inv_w + 1.0) * 0.5 * viewport.width;
  const double y_window = (1.0 - double(p_clip.y) * inv_w) * 0.5 * viewport.height;
  // Inside the guard band (+ margin) => |window| < 2^15, so fixed values fit in 24 bits.
  constexpr double kLimit = 32768.0 - 1.0;
  if (!(std::fabs(x_window) < kLimit && std::fabs(y_window) < kLimit)) {
    v.outcode = kInvalidVertex;
    return;
  }
  const double x_scaled = x_window * kSubpixelOne, y_scaled = y_window * kSubpixelOne;
  v.x = round_to_fixed(x_scaled);
  v.y = round_to_fixed(y_scaled);
  v.inv_w = float(inv_w);
  // The residuals and the key from the point in double (project_eight: the same operations).
  const double inv_w_exact = 1.0 / exact.w;
  const double xe = (exact.x * inv_w_exact + 1.0) * 0.5 * viewport.width;
  const double ye = (1.0 - exact.y * inv_w_exact) * 0.5 * viewport.height;
  if (exact.w > 0.0 && exact.depth > 0.0 && std::fabs(xe) < kLimit && std::fabs(ye) < kLimit) {
    v.dx = float(xe * kSubpixelOne - v.x);
    v.dy = float(ye * kSubpixelOne - v.y);
    v.key = float(orthographic ? -exact.depth : 1.0 / exact.depth);
  } else {
    v.dx = float(x_scaled - v.x);  // the subtraction is exact; float keeps 2^-24 of a subpixel
    v.dy = float(y_scaled - v.y);
    v.key = orthographic ? -depth_view : 1.0f / depth_view;
  }
}

namespace {

using namespace simd;

static_assert(sizeof(ProjectedVertex) == kLanes * sizeof(int32_t) &&
                  offsetof(ProjectedVertex, dx) == 8 && offsetof(ProjectedVertex, key) == 16 &&
                  offsetof(ProjectedVertex, inv_w) == 20 && offsetof(ProjectedVertex, outcode) == 24,
              "project_eight writes a ProjectedVertex as eight 32-bit words");

// Eight vertices [i, i + 8) at once, lane by lane the operations of transform_point and project
// (IEEE operations in the same order, no contraction), so the same bits. A vertex that project()
// would not write plainly (outside a plane, not finite, w <= 0, outside the guard band's limit)
// is redone by project() itself afterwards.
// Lanes 0-3 (h = 0) or 4-7 of v, in double. An SR_INLINE function, not a lambda: a lambda that is
// not inlined (as at -O0) is compiled for the generic target, and its AVX2 caller's eight-lane
// argument arrives wrong (the sanitizer build at -O0 found this one).
SR_INLINE d4 half_of(f8 v, int h) {
  return __builtin_convertvector(h == 0 ? low_half(v) : high_half(v), d4);
}

// transform.hpp's exact_row, four lanes at a time.
SR_INLINE d4 exact_row4(const dmat4& a, int r, d4 x, d4 y, d4 z) {
  return (broadcast<d4>(a[0][r]) * x + broadcast<d4>(a[1][r]) * y) +
         (broadcast<d4>(a[2][r]) * z + broadcast<d4>(a[3][r]));
}

template <bool kWIsDepth>
SR_INLINE void project_eight(const vec3* positions, const DrawTransform& xf, std::size_t i,
                             const ClipPlanes& planes, const Viewport& viewport, bool orthographic,
                             ProjectedVertex* out) {
  f8 px, py, pz;
  load_xyz8(&positions[i].x, px, py, pz);

  const mat4& m = xf.model_view;
  const mat4& proj = xf.proj;
  f8 v[4], clip[4];
  for (int r = 0; r < 4; ++r)
    v[r] = (splat(m[0][r]) * px + splat(m[1][r]) * py) + (splat(m[2][r]) * pz + splat(m[3][r]));
  for (int r = 0; r < 4; ++r)
    clip[r] = (splat(proj[0][r]) * v[0] + splat(proj[1][r]) * v[1]) +
              (splat(proj[2][r]) * v[2] + splat(proj[3][r]) * v[3]);
  const f8 depth_view = -v[2];

  const i8 exponent = splat(int32_t(0x7f800000));
  const i8 finite = ((float_bits(clip[0]) & exponent) != exponent) &
                    ((float_bits(clip[1]) & exponent) != exponent) &
                    ((float_bits(clip[2]) & exponent) != exponent) &
                    ((float_bits(clip[3]) & exponent) != exponent) &
                    ((float_bits(depth_view) & exponent) != exponent);
  unsigned plain = mask_bits(finite);

  // The double-precision part, four lanes at a time.
  constexpr double kLimit = 32768.0 - 1.0;
  const l4 sign = broadcast<l4>(int64_t(0x8000000000000000ull)), half = l4(broadcast<d4>(0.5));
  const double width = double(viewport.width), height = double(viewport.height);
  i4 fixed[2][2];  // [x / y][half]
  f4 residual[2][2], inv_w_f[2], key_f[2];
  const dmat4& c = xf.model_view_proj_d;
  const dmat4& mv = xf.model_view_d;
  for (int h = 0; h < 2; ++h) {
    const d4 x = half_of(clip[0], h), y = half_of(clip[1], h), w = half_of(clip[3], h),
             d = half_of(depth_view, h);
    // ClipPlanes::outcode() == 0, project()'s w > 0 and depth > 0, and its window-limit test.
    l4 inside = (d - planes.near >= 0.0) & (planes.far - d >= 0.0) &
                (x - planes.ndc_x_min * w >= 0.0) & (planes.ndc_x_max * w - x >= 0.0) &
                (planes.ndc_y_max * w - y >= 0.0) & (y - planes.ndc_y_min * w >= 0.0) &
                (w > 0.0) & (d > 0.0);
    const d4 inv_w = 1.0 / w;
    const d4 window[2] = {(x * inv_w + 1.0) * 0.5 * width, (1.0 - y * inv_w) * 0.5 * height};
    // The same point in double (transform.hpp, exact_clip): the residuals and the key.
    const d4 px_d = half_of(px, h), py_d = half_of(py, h), pz_d = half_of(pz, h);
    const d4 xe = exact_row4(c, 0, px_d, py_d, pz_d), ye = exact_row4(c, 1, px_d, py_d, pz_d);
    // (With w_is_depth, w and the depth are the same bits, and so are their reciprocals.)
    const d4 we = exact_row4(c, 3, px_d, py_d, pz_d);
    d4 de;
    if constexpr (kWIsDepth) de = we;
    else de = -exact_row4(mv, 2, px_d, py_d, pz_d);
    const d4 inv_we = 1.0 / we;
    const d4 window_e[2] = {(xe * inv_we + 1.0) * 0.5 * width, (1.0 - ye * inv_we) * 0.5 * height};
    // project()'s test for the double point; a lane that fails it is redone there.
    inside &= (we > 0.0) & (de > 0.0);
    for (int k = 0; k < 2; ++k) {
      inside &= d4(l4(window[k]) & ~sign) < kLimit;  // |window| < kLimit
      inside &= d4(l4(window_e[k]) & ~sign) < kLimit;
      // round_to_fixed: + or - 1/2 by the sign bit, then truncate.
      const d4 scaled = window[k] * double(kSubpixelOne);
      fixed[k][h] = __builtin_convertvector(scaled + d4((l4(scaled) & sign) | half), i4);
      residual[k][h] = __builtin_convertvector(
          window_e[k] * double(kSubpixelOne) - __builtin_convertvector(fixed[k][h], d4), f4);
    }
    inv_w_f[h] = __builtin_convertvector(inv_w, f4);
    key_f[h] = __builtin_convertvector(orthographic ? -de : kWIsDepth ? inv_we : 1.0 / de, f4);
    plain &= mask_bits(inside) << (4 * h) | (0xfu << (4 - 4 * h));
  }
  const auto join = [](auto lo, auto hi) {
    return __builtin_shufflevector(lo, hi, 0, 1, 2, 3, 4, 5, 6, 7);
  };
  const i8 xi = join(fixed[0][0], fixed[0][1]), yi = join(fixed[1][0], fixed[1][1]);
  const f8 dx = join(residual[0][0], residual[0][1]), dy = join(residual[1][0], residual[1][1]);
  const f8 key = join(key_f[0], key_f[1]);
  const f8 inv_w_8 = join(inv_w_f[0], inv_w_f[1]);

  // Eight records: an 8x8 transpose of (x, y, dx, dy, key, inv_w, outcode = 0, padding = 0).
  i8 rows[8] = {xi, yi, float_bits(dx), float_bits(dy), float_bits(key), float_bits(inv_w_8), i8{}, i8{}};
  transpose8(rows);
  ProjectedVertex* o = out + i;
  for (int k = 0; k < 8; ++k) store(o + k, rows[k]);

  for (unsigned redo = ~plain & 0xffu; redo != 0; redo &= redo - 1) {
    const int k = __builtin_ctz(redo);
    const ClipVertex cv = transform_point(xf, positions[i + k]);
    project(cv.p_clip, cv.depth_view, exact_clip(xf, positions[i + k]), planes, viewport,
            orthographic, false, o[k]);
  }
}

SR_INLINE void project_range(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                             std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                             bool orthographic, ProjectedVertex* out) {
  const vec3* positions = mesh.positions.data();
  std::size_t i = begin;
  for (; i + kLanes <= end; i += kLanes)
    if (xf.w_is_depth) project_eight<true>(positions, xf, i, planes, viewport, orthographic, out);
    else project_eight<false>(positions, xf, i, planes, viewport, orthographic, out);
  for (; i < end; ++i) {
    const ClipVertex c = transform_point(xf, positions[i]);
    project(c.p_clip, c.depth_view, exact_clip(xf, positions[i]), planes, viewport, orthographic,
            false, out[i]);
  }
}

struct ProjectRange {
  SR_INLINE static void run(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                            std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                            bool orthographic, ProjectedVertex* out) {
    project_range(mesh, xf, begin, end, planes, viewport, orthographic, out);
  }
};
using ProjectRangeFn = void (*)(const MeshData&, const DrawTransform&, std::size_t, std::size_t,
                                const ClipPlanes&, const Viewport&, bool, ProjectedVertex*);

}  // namespace

void project_vertices(const MeshData& mesh, const DrawTransform& xf, std::size_t begin,
                      std::size_t end, const ClipPlanes& planes, const Viewport& viewport,
                      bool orthographic, Isa isa, ProjectedVertex* out) {
  dispatch::IsaKernel<ProjectRange, ProjectRangeFn>::get(isa)(mesh, xf, begin, end, planes,
                                                             viewport, orthographic, out);
}

}  // namespace sr
