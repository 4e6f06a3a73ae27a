// Lens distortion's per-pixel resolve and bilinear gathers (distortion.hpp).
#include "distortion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <exception>
#include <thread>
#include <type_traits>

namespace sr {
namespace {

constexpr double kHitTolerance = 1e-9;  // barycentric slack: a ray on a shared edge hits both

struct Intersection {
  double t = std::numeric_limits<double>::quiet_NaN();
  double b[3] = {0.0, 0.0, 0.0};
};

// The ray from the camera centre along `dir` (world) against one face, Moeller-Trumbore in
// double, in the instance's model space: an affine map keeps a ray's parameter t and the
// barycentric weights, and the corners need no transform (the ray is mapped once, relative to
// the camera centre's model-space image, so far scenes keep their digits).
Intersection intersect(const RayInstance& inst, int32_t face, const dvec3& dir) {
  Intersection r;
  const ivec3 f = inst.mesh->faces[std::size_t(face)];
  dvec3 c[3];
  for (int k = 0; k < 3; ++k) c[k] = dvec3(inst.mesh->positions[std::size_t(f[k])]) - inst.origin;
  const dvec3 d = inst.inverse_linear * dir;
  const dvec3 e1 = c[1] - c[0], e2 = c[2] - c[0];
  const dvec3 pvec = glm::cross(d, e2);
  const double det = glm::dot(e1, pvec);
  if (det == 0.0 || !std::isfinite(det)) return r;  // the ray lies in the face's plane: t stays NaN
  const double inv = 1.0 / det;
  const dvec3 tvec = -c[0];
  const double b1 = glm::dot(tvec, pvec) * inv;
  const dvec3 qvec = glm::cross(tvec, e1);
  const double b2 = glm::dot(d, qvec) * inv;
  r.t = glm::dot(e2, qvec) * inv;
  r.b[0] = 1.0 - b1 - b2;
  r.b[1] = b1;
  r.b[2] = b2;
  return r;
}

// The face's corner k posed, relative to the camera centre.
dvec3 world_corner(const RayInstance& inst, int32_t face, int k, const dvec3& centre) {
  const vec3 p = inst.mesh->positions[std::size_t(inst.mesh->faces[std::size_t(face)][k])];
  return dvec3(inst.model * dvec4(dvec3(p), 1.0)) - centre;
}

bool hits(const Intersection& r) {
  return r.t > 0.0 && r.b[0] >= -kHitTolerance && r.b[1] >= -kHitTolerance && r.b[2] >= -kHitTolerance;
}

void resolve_range(const DistortionRays& rays, const int32_t* triangle_id, const int32_t* instance,
                   const std::vector<RayInstance>& instances, const dmat3& camera_to_world,
                   const dvec3& centre, const DistortionHits& out, int64_t begin, int64_t end) {
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
  for (int64_t p = begin; p < end; ++p) {
    const int64_t nearest = rays.nearest[p];
    out.sample[p] = nearest;
    out.covered[p] = 0;
    // Zeros where nothing is seen (background), every output written for every pixel.
    if (out.depth) out.depth[p] = 0.0;
    if (out.ray_depth) out.ray_depth[p] = 0.0;
    if (out.position) std::fill(out.position + 3 * p, out.position + 3 * p + 3, 0.0);
    if (out.barycentric) std::fill(out.barycentric + 3 * p, out.barycentric + 3 * p + 3, 0.0);
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
      const Intersection r = intersect(*inst, f, dir);
      if (hits(r)) best = r, best_sample = nearest;
    }
    if (best_sample < 0) {
      for (const int64_t s : {c, c + 1, c + w, c + w + 1}) {
        const int32_t f = face_of(s, inst);
        if (f < 0) continue;
        const Intersection r = intersect(*inst, f, dir);
        if (hits(r) && (best_sample < 0 || r.t < best.t)) best = r, best_sample = s;
      }
    }
    dvec3 point;  // relative to the camera centre
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
      const Intersection r = intersect(*inst, f, sdir);
      const bool grazing = !std::isfinite(r.t);
      double sum = 0.0;
      for (int k = 0; k < 3; ++k) {  // the vertex snap can leave the sample's ray just outside
        b[k] = grazing ? 1.0 / 3.0 : std::clamp(r.b[k], 0.0, 1.0);
        sum += b[k];
      }
      for (double& x : b) x /= sum;
      if (!grazing && r.t > 0.0) {
        point = r.t * sdir;
      } else {
        point = dvec3(0.0);
        for (int k = 0; k < 3; ++k) point += b[k] * world_corner(*inst, f, k, centre);
      }
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

}  // namespace

void resolve_distorted(const DistortionRays& rays, const int32_t* triangle_id, const int32_t* instance,
                       std::vector<RayInstance> instances, const dmat3& camera_to_world,
                       const dvec3& centre, const DistortionHits& out, int threads) {
  for (RayInstance& inst : instances) {  // the camera centre and ray directions in model space
    const dmat3 linear(inst.model);
    const double det = glm::determinant(linear);
    if (!(std::isfinite(det) && det != 0.0))  // a flattened instance: its faces hit nothing
      inst.inverse_linear = dmat3(0.0);
    else
      inst.inverse_linear = glm::inverse(linear);
    inst.origin = inst.inverse_linear * (centre - dvec3(inst.model[3]));
  }
  const int n_threads = int(std::clamp<int64_t>(threads, 1, std::max<int64_t>(1, rays.n / 4096)));
  if (n_threads == 1) {
    resolve_range(rays, triangle_id, instance, instances, camera_to_world, centre, out, 0, rays.n);
    return;
  }
  // Rows of pixels in equal parts; each part writes only its own pixels (same bits for any count).
  std::vector<std::exception_ptr> errors(static_cast<std::size_t>(n_threads));
  std::vector<std::thread> workers;
  auto part = [&](int k) {
    try {
      resolve_range(rays, triangle_id, instance, instances, camera_to_world, centre, out,
                    rays.n * k / n_threads, rays.n * (k + 1) / n_threads);
    } catch (...) {
      errors[std::size_t(k)] = std::current_exception();
    }
  };
  for (int k = 1; k < n_threads; ++k) workers.emplace_back(part, k);
  part(0);
  for (std::thread& t : workers) t.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
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
