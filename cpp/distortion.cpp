// Lens distortion's per-pixel resolve and bilinear gathers (distortion.hpp).
#include "distortion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

namespace sr {
namespace {

constexpr double kHitTolerance = 1e-9;  // barycentric slack: a ray on a shared edge hits both

struct Intersection {
  double t = std::numeric_limits<double>::quiet_NaN();
  double b[3] = {0.0, 0.0, 0.0};
  dvec3 corners[3];  // posed, relative to the camera centre (far scenes keep their digits)
};

// The ray from the camera centre along `dir` against one face (Moeller-Trumbore, double).
Intersection intersect(const RayInstance& inst, int32_t face, const dvec3& dir, const dvec3& centre) {
  Intersection r;
  const ivec3 f = inst.mesh->faces[std::size_t(face)];
  for (int k = 0; k < 3; ++k) {
    const vec3 p = inst.mesh->positions[std::size_t(f[k])];
    const dvec4 w = inst.model * dvec4(double(p.x), double(p.y), double(p.z), 1.0);
    r.corners[k] = dvec3(w) - centre;
  }
  const dvec3 e1 = r.corners[1] - r.corners[0], e2 = r.corners[2] - r.corners[0];
  const dvec3 pvec = glm::cross(dir, e2);
  const double det = glm::dot(e1, pvec);
  if (det == 0.0) return r;  // the ray lies in the face's plane: t stays NaN
  const double inv = 1.0 / det;
  const dvec3 tvec = -r.corners[0];
  const double b1 = glm::dot(tvec, pvec) * inv;
  const dvec3 qvec = glm::cross(tvec, e1);
  const double b2 = glm::dot(dir, qvec) * inv;
  r.t = glm::dot(e2, qvec) * inv;
  r.b[0] = 1.0 - b1 - b2;
  r.b[1] = b1;
  r.b[2] = b2;
  return r;
}

bool hits(const Intersection& r) {
  return r.t > 0.0 && r.b[0] >= -kHitTolerance && r.b[1] >= -kHitTolerance && r.b[2] >= -kHitTolerance;
}

}  // namespace

void resolve_distorted(const DistortionRays& rays, const int32_t* triangle_id, const int32_t* instance,
                       const std::vector<RayInstance>& instances, const dmat3& camera_to_world,
                       const dvec3& centre, const DistortionHits& out) {
  const int64_t w = rays.view_width;
  auto face_of = [&](int64_t s, const RayInstance*& inst) -> int32_t {
    const int32_t tri = triangle_id[s];
    if (tri < 0) return -1;
    const int32_t k = instance[s];
    if (k < 0 || std::size_t(k) >= instances.size() ||
        std::size_t(tri) >= instances[std::size_t(k)].mesh->faces.size())
      throw std::invalid_argument("resolve_distorted: a view id names no instance or face");
    inst = &instances[std::size_t(k)];
    return tri;
  };
  for (int64_t p = 0; p < rays.n; ++p) {
    const int64_t nearest = rays.nearest[p];
    out.sample[p] = nearest;
    out.covered[p] = 0;
    if (!rays.valid[p]) continue;
    const double* d = rays.directions + 3 * p;
    const dvec3 dir = camera_to_world * dvec3(d[0], d[1], d[2]);
    const int64_t c = rays.corner[p];
    // The nearest sample's triangle first; where the ray misses it, the nearest hit of the four
    // samples around the ray's point.
    Intersection best;
    int64_t best_sample = -1;
    const RayInstance* inst = nullptr;
    if (const int32_t f = face_of(nearest, inst); f >= 0) {
      Intersection r = intersect(*inst, f, dir, centre);
      if (hits(r)) best = r, best_sample = nearest;
    }
    if (best_sample < 0) {
      for (const int64_t s : {c, c + 1, c + w, c + w + 1}) {
        const int32_t f = face_of(s, inst);
        if (f < 0) continue;
        Intersection r = intersect(*inst, f, dir, centre);
        if (hits(r) && (best_sample < 0 || r.t < best.t)) best = r, best_sample = s;
      }
    }
    dvec3 point;
    double b[3];
    if (best_sample >= 0) {
      point = best.t * dir;
      std::copy(best.b, best.b + 3, b);
    } else {
      // Missed every candidate: the nearest sample's triangle, at the sample's own point (its
      // centre's ray meets the triangle it covered), half a sample diagonal away at most.
      const int32_t f = face_of(nearest, inst);
      if (f < 0) continue;  // background
      best_sample = nearest;
      const int64_t i = nearest / w, j = nearest % w;
      const double* m = rays.sample_to_normalized;
      const dvec3 sdir = camera_to_world * dvec3(double(j) * m[0] + m[1], double(i) * m[2] + m[3], 1.0);
      const Intersection r = intersect(*inst, f, sdir, centre);
      const bool grazing = !std::isfinite(r.t);
      double sum = 0.0;
      for (int k = 0; k < 3; ++k) {  // the vertex snap can leave the sample's ray just outside
        b[k] = grazing ? 1.0 / 3.0 : std::clamp(r.b[k], 0.0, 1.0);
        sum += b[k];
      }
      for (double& x : b) x /= sum;
      point = (!grazing && r.t > 0.0) ? r.t * sdir
                                      : b[0] * r.corners[0] + b[1] * r.corners[1] + b[2] * r.corners[2];
    }
    out.sample[p] = best_sample;
    out.covered[p] = 1;
    if (out.depth) out.depth[p] = glm::dot(point, camera_to_world[2]);  // OpenCV's +z axis
    if (out.ray_depth) out.ray_depth[p] = glm::length(point);
    if (out.position)
      for (int k = 0; k < 3; ++k) out.position[3 * p + k] = point[k] + centre[k];
    if (out.barycentric) std::copy(b, b + 3, out.barycentric + 3 * p);
  }
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
