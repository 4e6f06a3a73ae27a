// World normals: each mesh vertex's normal in world space, unit length, once per render rather
// than once per triangle corner and tile (shading reads them by vertex index).
#pragma once

#include "pipeline.hpp"
#include "simd.hpp"

#include <cmath>

namespace sr {

// Unit vector in float, or zero for a zero (or non-finite) vector.
inline vec3 unit(const dvec3& v) {
  const double len = glm::length(v);
  return len > 0.0 && std::isfinite(len) ? vec3(v / len) : vec3(0.0f);
}

// World-space unit normals of vertices [begin, end) of a mesh with vertex normals.
void world_normals(const MeshData& mesh, const dmat3& normal_to_world, std::size_t begin,
                   std::size_t end, Isa isa, vec3* out);

}  // namespace sr
