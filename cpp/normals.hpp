// World normals: each mesh vertex's normal in world space, unit length, once per render rather
// than once per triangle corner and tile (shading reads them by vertex index).
#pragma once

#include "pipeline.hpp"
#include "simd.hpp"

#include <cmath>

namespace sr {

// unit(v) where |v|^2 over- or underflows double (|v| below 2^-510 or infinite): v scaled by a
// power of two to a largest component in [1, 2) first (exact), so any finite nonzero v has a unit
// result; zero for a zero or non-finite v. Out of line: it runs only at such extremes.
[[gnu::cold]] vec3 unit_rescaled(double x, double y, double z);  // (in registers: no spill)

// Unit vector in float, or zero for a zero (or non-finite) vector. A vector whose length is in
// [2^-510, inf) is divided by it directly (its squared length is a normal double); any other
// finite one is rescaled first (unit_rescaled): unit for every finite nonzero v, whatever its
// magnitude (a normal matrix of 1e200 on a face normal of 1e-30, a normal of 1e-160).
inline vec3 unit(const dvec3& v) {
  const double len = glm::length(v);
  return len >= 0x1p-510 && std::isfinite(len) ? vec3(v / len) : unit_rescaled(v.x, v.y, v.z);
}

// The counter-clockwise face normal of corners c0, c1, c2 of `positions`, (p1 - p0) x (p2 - p0)
// in double, unnormalised, taken at the corner opposite the longest edge (the largest angle, at
// least 60 degrees): the cyclic order kept, so the same orientation, and no cancellation where
// another corner's angle is tiny (a corner 1e19 away from two unit-scale ones). Out of line and
// cold: flat_normal calls it only for such faces.
[[gnu::cold]] dvec3 well_conditioned_cross(const vec3* positions, int32_t c0, int32_t c1, int32_t c2);

// World-space unit normals of vertices [begin, end) of a mesh with vertex normals.
void world_normals(const MeshData& mesh, const dmat3& normal_to_world, std::size_t begin,
                   std::size_t end, Isa isa, vec3* out);

}  // namespace sr
