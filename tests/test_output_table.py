"""The core's output table (cpp/framebuffer.hpp) is the one source of every list of outputs:
each row's dtype, shape, bytes and background value are what a render returns."""
from __future__ import annotations

import numpy as np

import softrast as sr
from conftest import icosphere


def _render(outputs):
    scene = sr.Scene()
    scene.add(icosphere(2))
    cam = sr.PerspectiveCamera(fov_y=45.0, near=0.1, far=10.0)
    cam.look_at((0, 0, 4), (0, 0, 0))
    return sr.Renderer(40, 30).render(scene, cam, outputs=outputs)


def test_every_row_describes_what_a_render_returns():
    frame = _render(sr.OUTPUTS)
    assert tuple(row["name"] for row in sr.OUTPUT_TABLE) == sr.OUTPUTS == sr.Frame.__slots__
    for row in sr.OUTPUT_TABLE:
        arr = getattr(frame, row["name"])
        shape = (30, 40) if row["channels"] == 1 else (30, 40, row["channels"])
        assert arr.shape == shape and arr.dtype == row["dtype"], row["name"]
        assert arr.nbytes == 30 * 40 * row["bytes_per_pixel"]
        doc_shape = "(h, w)" if row["channels"] == 1 else f"(h, w, {row['channels']})"
        assert row["pass"] in ("resolve", "shade", "surface") and row["doc"].startswith(doc_shape), row["name"]
        if row["name"] != "color":  # colour's background is the render's option
            bg = arr[~frame.mask]
            assert bg.size and (bg == np.asarray(row["background"], dtype=row["dtype"])).all(), row["name"]


def test_frame_docstring_and_budget_come_from_the_table():
    for row in sr.OUTPUT_TABLE:
        assert row["name"] in sr.Frame.__doc__ and row["doc"][:20] in sr.Frame.__doc__
    from softrast import render
    assert render._OUTPUT_BYTES == {r["name"]: r["bytes_per_pixel"] for r in sr.OUTPUT_TABLE}
