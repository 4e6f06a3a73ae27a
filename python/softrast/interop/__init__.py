"""Conversions between pyrender and softrast scenes: ``softrast.from_pyrender`` and
``softrast.to_pyrender``.

from_pyrender (``_from_pyrender``) never imports pyrender: its objects are read by their
attributes (duck typing), so softrast works without pyrender installed, and a pyrender scene
converts without an OpenGL context. to_pyrender (``_to_pyrender``) imports pyrender when it is
called, never at ``import softrast``; whatever does not convert exactly gets one UserWarning
naming it. What converts, how, and where the two renderers differ (materials, textures,
lights, cameras, background, blending, instances) is described in one place.
See docs/interop.md.
"""
from __future__ import annotations

from ._from_pyrender import PyrenderConversion, from_pyrender
from ._from_pyrender import _material  # noqa: F401 (tests convert a material alone)
from ._to_pyrender import to_pyrender

__all__ = ["PyrenderConversion", "from_pyrender", "to_pyrender"]

PyrenderConversion.__module__ = __name__  # pickles and reprs name the public path, as before
