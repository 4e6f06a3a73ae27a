"""softrast's independent NumPy references: what the renderer promises, written from the formulas
and the rules (the docstrings of softrast.material, light, texture, docs/pbr_notes.md, the raster
rules), never from the C++ core, which they do not call. The tests check the renderer against them,
``softrast report`` reads its closed-form shading from them, and benchmarks/check_reference_vs_pyrender.py
checks them against pyrender.

The modules, lowest first (each imports NumPy and the ones before it only):

``encoding``
    the sRGB transfer curve and its inverse, and the 8-bit encodings (sRGB, linear, pyrender's).
``shading``
    the shading models (unlit, lambert, phong, blinn_phong, pbr as pyrender's compute_brdf,
    normal), the lights (directional, point, spot; the headlight), world positions from depth.
``texture``
    the texture sampler: decoding, the box-filtered mip chain, wrapping, nearest / bilinear /
    trilinear / anisotropic filtering, with the core's float32 coordinate arithmetic.
``raster``
    coverage of pixel centres: 1/256 px snapping, exact integer edge functions, the top-left
    rule, culling.
``triangles``
    a camera at the origin and the triangles of a draw in window space (for ``blend``).
``blend``
    order-independent alpha blending: every fragment, sorted and composited.
``shadow``
    exact shadows: the shadow-ray rule and its margin.

Import the module you need: ``from softrast.reference import shading``.
"""
from __future__ import annotations

from . import blend, encoding, raster, shading, shadow, texture, triangles

__all__ = ["blend", "encoding", "raster", "shading", "shadow", "texture", "triangles"]
