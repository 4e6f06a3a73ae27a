"""Helpers for the tests, not tests themselves: independent NumPy references (raster, shading,
blending, shadows, textures, an exact ray caster), the golden scenes and their recorder, and the
child scripts and runner for pyrender on OSMesa. The test files import them as
``from support import raster_reference as ref`` (pytest puts tests/ on sys.path: tests/ has a
conftest.py and no __init__.py). The golden recorders and the pyrender children also run as
scripts by path, e.g. ``python3 tests/support/golden.py --write <commit>``."""
