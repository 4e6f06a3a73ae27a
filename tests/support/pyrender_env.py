"""pyrender on Mesa's OSMesa (llvmpipe) for the child processes that run it
(tests/support/pyrender_child.py, tests/support/pyrender_interop_child.py): the platform is chosen
before OpenGL is imported, NumPy 2's removed ``np.infty`` is restored for pyrender 0.1.45, and a
failed import exits with status 3 and one line saying why (the tests turn that into install
instructions)."""
import os
import sys

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")

import numpy as np  # noqa: E402

if not hasattr(np, "infty"):  # pyrender 0.1.45's Mesh.bounds uses np.infty (removed in NumPy 2)
    np.infty = np.inf


def import_pyrender(who: str):
    """(pyrender, trimesh), or exit 3 naming ``who`` and the import failure."""
    try:
        import pyrender
        import trimesh
    except Exception as exc:  # ImportError, or PyOpenGL failing to find libOSMesa
        sys.stderr.write(f"{who}: cannot import pyrender with OSMesa: {type(exc).__name__}: {exc}\n")
        sys.exit(3)
    return pyrender, trimesh
