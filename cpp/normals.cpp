// World normals: the normal matrix applied to every vertex normal, eight at a time.
#include "normals.hpp"

#include "dispatch.hpp"

#include <algorithm>
#include <cmath>

namespace sr {

namespace {

using namespace simd;

// World-space unit normals. The unit normal does not depend on the matrix's scale, so the matrix
// is scaled to a largest entry of 1 and the work done in float, eight normals at a time; a normal
// whose transformed squared length is outside [2^-100, 2^100] (a zero normal, or one scaled near
// float's limits) is redone as unit(m * dvec3(n)) in double. The scalar loop that finishes the
// range repeats the float operations (grouped as GLM groups them), so the same bits.
struct NormalMatrix {
  dmat3 m;     // normal_to_world
  float f[3][3];  // m / max |m_ij|, columns first
  explicit NormalMatrix(const dmat3& matrix) : m(matrix) {
    double largest = 0.0;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) largest = std::max(largest, std::fabs(m[c][r]));
    const double scale = largest > 0.0 && std::isfinite(largest) ? 1.0 / largest : 0.0;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) f[c][r] = float(m[c][r] * scale);
  }
};
constexpr float kMinNormalLength2 = 0x1p-100f, kMaxNormalLength2 = 0x1p100f;

inline vec3 unit_world_normal(const NormalMatrix& nm, const vec3& n) {
  float w[3];
  for (int r = 0; r < 3; ++r) w[r] = (nm.f[0][r] * n.x + nm.f[1][r] * n.y) + nm.f[2][r] * n.z;
  const float len2 = (w[0] * w[0] + w[1] * w[1]) + w[2] * w[2];
  if (!(len2 >= kMinNormalLength2 && len2 <= kMaxNormalLength2)) return unit(nm.m * dvec3(n));
  const float r = 1.0f / std::sqrt(len2);
  return vec3(w[0] * r, w[1] * r, w[2] * r);
}

SR_INLINE void world_normals_range(const MeshData& mesh, const NormalMatrix& nm, std::size_t begin,
                                   std::size_t end, vec3* out) {
  const vec3* normals = mesh.normals.data();
  std::size_t i = begin;
  for (; i + kLanes <= end; i += kLanes) {
    f8 x, y, z;
    load_xyz8(&normals[i].x, x, y, z);
    f8 w[3];
    for (int r = 0; r < 3; ++r)
      w[r] = (splat(nm.f[0][r]) * x + splat(nm.f[1][r]) * y) + splat(nm.f[2][r]) * z;
    const f8 len2 = (w[0] * w[0] + w[1] * w[1]) + w[2] * w[2];
    const i8 ok = (len2 >= splat(kMinNormalLength2)) & (len2 <= splat(kMaxNormalLength2));
    const f8 r = 1.0f / simd::sqrt(len2);
    const f8 u[3] = {w[0] * r, w[1] * r, w[2] * r};
    // Back to xyz triples.
    const f8 t_a = __builtin_shufflevector(u[0], u[1], 0, 8, 0, 1, 9, 0, 2, 10);
    const f8 t_b = __builtin_shufflevector(u[0], u[1], 0, 3, 11, 0, 4, 12, 0, 5);
    const f8 t_c = __builtin_shufflevector(u[0], u[1], 13, 0, 6, 14, 0, 7, 15, 0);
    store(&out[i].x, __builtin_shufflevector(t_a, u[2], 0, 1, 8, 3, 4, 9, 6, 7));
    store(&out[i].x + 8, __builtin_shufflevector(t_b, u[2], 10, 1, 2, 11, 4, 5, 12, 7));
    store(&out[i].x + 16, __builtin_shufflevector(t_c, u[2], 0, 13, 2, 3, 14, 5, 6, 15));
    if (!all(ok))
      for (int k = 0; k < kLanes; ++k)
        if (!ok[k]) out[i + k] = unit(nm.m * dvec3(normals[i + k]));
  }
  for (; i < end; ++i) out[i] = unit_world_normal(nm, normals[i]);
}

struct WorldNormals {
  SR_INLINE static void run(const MeshData& mesh, const NormalMatrix& nm, std::size_t begin,
                            std::size_t end, vec3* out) {
    world_normals_range(mesh, nm, begin, end, out);
  }
};
using WorldNormalsFn = void (*)(const MeshData&, const NormalMatrix&, std::size_t, std::size_t, vec3*);

}  // namespace

vec3 unit_rescaled(double x, double y, double z) {
  const dvec3 v(x, y, z);
  if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) return vec3(0.0f);
  const double largest = std::max(std::fabs(v.x), std::max(std::fabs(v.y), std::fabs(v.z)));
  if (largest == 0.0) return vec3(0.0f);
  const int e = std::ilogb(largest);  // largest in [2^e, 2^(e+1)), subnormals included
  const dvec3 w(std::ldexp(v.x, -e), std::ldexp(v.y, -e), std::ldexp(v.z, -e));
  return vec3(w / glm::length(w));  // |w| in [1, 2): no over- or underflow
}

dvec3 well_conditioned_cross(const vec3* positions, int32_t c0, int32_t c1, int32_t c2) {
  const dvec3 p[3] = {dvec3(positions[c0]), dvec3(positions[c1]), dvec3(positions[c2])};
  // Edge k runs from corner k + 1 to corner k + 2, opposite corner k.
  int corner = 0;
  double longest = -1.0;
  for (int k = 0; k < 3; ++k) {
    const dvec3 e = p[(k + 2) % 3] - p[(k + 1) % 3];
    const double len2 = glm::dot(e, e);
    if (len2 > longest) longest = len2, corner = k;
  }
  const dvec3& a = p[corner];
  return glm::cross(p[(corner + 1) % 3] - a, p[(corner + 2) % 3] - a);
}

void world_normals(const MeshData& mesh, const dmat3& normal_to_world, std::size_t begin,
                   std::size_t end, Isa isa, vec3* out) {
  const NormalMatrix nm(normal_to_world);
  dispatch::IsaKernel<WorldNormals, WorldNormalsFn>::get(isa)(mesh, nm, begin, end, out);
}

}  // namespace sr
