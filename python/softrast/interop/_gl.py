"""The OpenGL enums pyrender's objects carry (primitive modes, sampler wraps and filters), shared
by both directions of the conversion."""
from __future__ import annotations

_TRIANGLES = 4  # GL_TRIANGLES, pyrender's default primitive mode
_POINTS, _LINES = 0, 1  # GL_POINTS, GL_LINES
_GL_WRAP = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
_WRAP_GL = {name: enum for enum, name in _GL_WRAP.items()}
_GL_NEAREST, _GL_LINEAR = 9728, 9729
_GL_LINEAR_MIPMAP_LINEAR = 9987
