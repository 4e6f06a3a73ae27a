// The exact surface step (surface.hpp): rays and planes in double, view space.
#include "surface.hpp"

#include <cmath>

namespace sr {

ViewRays make_view_rays(const dmat4& proj, int width, int height, bool orthographic) {
  // A window point's NDC is (2 x / W - 1, 1 - 2 y / H) (vertex.cpp, project), so the near-plane
  // point inv (ndc, -1, 1) is affine in (x, y). (glm: inv[c] is column c.)
  const dmat4 inv = glm::inverse(proj);
  const dvec4 q0 = inv * dvec4(-1.0, 1.0, -1.0, 1.0);
  const dvec4 qx = inv[0] * (2.0 / width), qy = inv[1] * (-2.0 / height);
  ViewRays r;
  r.orthographic = orthographic;
  if (orthographic) {  // w stays 1: the origin is the near point, the direction far - near
    r.o0 = dvec3(q0);
    r.ox = dvec3(qx);
    r.oy = dvec3(qy);
    r.d0 = dvec3(inv[2] * 2.0);
  } else {  // through the camera centre: the near point's homogeneous xyz (any scale, any sign)
    r.d0 = dvec3(q0);
    r.dx = dvec3(qx);
    r.dy = dvec3(qy);
  }
  return r;
}

ExactTriangle exact_triangle(const dmat4& m, const vec3& c0, const vec3& c1, const vec3& c2) {
  auto pose = [&m](const vec3& p) {
    const double x = p.x, y = p.y, z = p.z;
    return dvec3(m[0][0] * x + m[1][0] * y + m[2][0] * z + m[3][0],
                 m[0][1] * x + m[1][1] * y + m[2][1] * z + m[3][1],
                 m[0][2] * x + m[1][2] * y + m[2][2] * z + m[3][2]);
  };
  ExactTriangle t;
  t.v0 = pose(c0);
  t.e1 = pose(c1) - t.v0;
  t.e2 = pose(c2) - t.v0;
  t.n = glm::cross(t.e1, t.e2);
  t.h = glm::dot(t.n, t.v0);
  const double nn = glm::dot(t.n, t.n);
  t.inv_nn = nn > 0.0 && std::isfinite(nn) && std::isfinite(t.h) ? 1.0 / nn : 0.0;
  return t;
}

namespace {

// The point where the ray through (x, y) meets the plane, or false.
inline bool plane_point(const ViewRays& rays, const ExactTriangle& tri, double x, double y,
                        dvec3& v) {
  if (tri.inv_nn == 0.0) return false;
  if (rays.orthographic) {
    const dvec3 o = rays.o0 + x * rays.ox + y * rays.oy;
    const double den = glm::dot(tri.n, rays.d0);
    if (den == 0.0) return false;
    v = o + ((tri.h - glm::dot(tri.n, o)) / den) * rays.d0;
  } else {
    const dvec3 d = rays.d0 + x * rays.dx + y * rays.dy;
    const double den = glm::dot(tri.n, d);
    if (den == 0.0) return false;
    v = d * (tri.h / den);
    if (!(v.z < 0.0)) return false;  // not in front of the camera
  }
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

bool exact_hit(const ViewRays& rays, const ExactTriangle& tri, double x, double y, ExactHit& hit) {
  if (!plane_point(rays, tri, x, y, hit.view)) return false;
  const dvec3 q = hit.view - tri.v0;
  hit.bary[1] = glm::dot(glm::cross(q, tri.e2), tri.n) * tri.inv_nn;
  hit.bary[2] = glm::dot(glm::cross(tri.e1, q), tri.n) * tri.inv_nn;
  hit.bary[0] = 1.0 - hit.bary[1] - hit.bary[2];
  return std::isfinite(hit.bary[1]) && std::isfinite(hit.bary[2]);
}

bool exact_depth(const ViewRays& rays, const ExactTriangle& tri, double x, double y, double& depth) {
  dvec3 v;
  if (!plane_point(rays, tri, x, y, v)) return false;
  depth = -v.z;
  return true;
}

}  // namespace sr
