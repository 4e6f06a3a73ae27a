// The only file that includes GLM and sets its configuration macros.
#pragma once

#define GLM_FORCE_CXX17
#define GLM_FORCE_SILENT_WARNINGS
#include <glm/glm.hpp>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <cstdint>

namespace sr {

using glm::dmat3;
using glm::dmat4;
using glm::dvec3;
using glm::dvec4;
using glm::ivec3;
using glm::mat3;
using glm::mat4;
using glm::vec2;
using glm::vec3;
using glm::vec4;

}  // namespace sr
