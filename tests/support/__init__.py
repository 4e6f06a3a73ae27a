"""Helpers for the tests, not tests themselves: an exact ray caster (``exact_hit``), exact per-pixel
answers (``exact_pixels``), the golden scenes and their recorder, a GIL probe, and the child scripts
and runner for pyrender on OSMesa. The NumPy references (shading, texture sampling, rasterization,
blending, shadows) are in the package: ``from softrast.reference import raster as ref``. The test
files import these helpers as ``from support import exact_hit as ex`` (pytest puts tests/ on
sys.path: tests/ has a conftest.py and no __init__.py). The golden recorders and the pyrender
children also run as scripts by path, e.g. ``python3 tests/support/golden.py --write <commit>``."""
