"""softrast's alpha blending (``alpha_mode="blend"``) against pyrender 0.1.45 on Mesa's llvmpipe.

pyrender runs in a child process (PYOPENGL_PLATFORM=osmesa), building its scenes directly from
the plain arrays given here (and once through ``softrast.to_pyrender``). What pyrender does with
alphaMode BLEND (its renderer.py and shaders): it draws the opaque meshes, then the translucent
ones sorted by the distance from the camera to each NODE's origin, farthest first, each with
``glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA)`` into an 8-bit RGBA framebuffer, with the
depth test and depth writes on. So pyrender blends whole meshes in node order, not fragments in
depth order, and it blends the values its shader writes:

* ``RenderFlags.FLAT`` writes the base colour factor as it is (no encoding), so FLAT blends
  those numbers. softrast composites in linear light and then encodes; with ``srgb=False`` it
  writes the linear composite as it is. Both are then the same arithmetic on the same numbers,
  so FLAT and ``shading="unlit", srgb=False`` must agree, and they do within 2/255 (pyrender
  rounds to 8 bits after every layer; softrast once).
* The lit shader writes pow(c, 1/2.2) per fragment, so pyrender's default render blends
  gamma-encoded colours, where softrast's ``color`` is the sRGB encoding of the linear-light
  composite. That difference is by design (compositing light is linear), not a tolerance:
  each renderer is checked against its own model (pyrender: the blend of pow(c, 1/2.2) values,
  within 2/255; softrast: sRGB(linear composite), within 1/255), and the two models are shown to
  differ by up to 18/255 here where layers of different colours overlap (2/255 on the opaque
  background alone: pyrender's gamma 2.2 against the sRGB curve).

Checked here:

* three separate translucent quads, each its own node at its own depth (not overlapping in
  depth, so pyrender's node sort gets the order right), over an opaque background quad: on
  interior pixels (the same set of layers in the whole 5x5 neighbourhood) softrast's unlit,
  srgb=False colour is the exact back-to-front composite within 1/255, pyrender's FLAT colour
  (built directly, and through to_pyrender) is within 2/255 of softrast's (1/255 measured),
  and every region (1, 2 and 3 layers over the background) is compared;
* two interpenetrating translucent quads: pyrender's image depends on which node it draws last
  (moved by placing the node origins, the world geometry the same): where the quad it draws
  last lies behind the other, the depth test drops it and that region shows one layer instead
  of two. softrast's image is the same whatever the draw order (byte for byte) and the node /
  vertex split (interior pixels), and is the exact depth-ordered composite on both sides of the
  intersection.

The test FAILS (never skips) without pyrender and OSMesa: see test_pbr_vs_pyrender.py.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from scipy import ndimage

import softrast as sr
from softrast.reference.encoding import srgb_curve as srgb_encode
from support.pyrender_runner import run_pyrender_script

W, H = 160, 120
FOV_Y = 40.0  # degrees
NEAR, FAR = 0.5, 20.0
EYE = (0.0, 0.0, 6.0)
BACKGROUND = (0.5, 0.45, 0.4, 1.0)  # the opaque quad behind everything (linear)
FLAT_TOL = 2  # bytes: pyrender FLAT against softrast unlit, srgb=False
MODEL_TOL = 1  # bytes: softrast against the exact composite

CHILD = r"""
import pickle, sys, warnings
sys.path.insert(0, sys.argv[1])  # tests/: support.pyrender_env
sys.path.insert(0, sys.argv[2])  # softrast's parent folder
from support.pyrender_env import import_pyrender
import numpy as np
pyrender, trimesh = import_pyrender("blend child")

with open(sys.argv[3], "rb") as f:
    jobs = pickle.load(f)
renderer = pyrender.OffscreenRenderer(jobs["width"], jobs["height"])
out = {}
for name, job in jobs["jobs"].items():
    warned = []
    if "softrast" in job:
        import softrast as sr
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            scene = sr.to_pyrender(*job["softrast"])
        warned = [str(c.message) for c in caught]
    else:
        scene = pyrender.Scene(ambient_light=job["ambient"], bg_color=[0.0, 0.0, 0.0, 1.0])
        for q in job["quads"]:
            material = pyrender.MetallicRoughnessMaterial(
                baseColorFactor=list(q["color"]), metallicFactor=0.0, roughnessFactor=1.0,
                doubleSided=True, alphaMode="BLEND" if q["blend"] else "OPAQUE")
            prim = pyrender.Primitive(positions=q["positions"], normals=q["normals"],
                                      indices=q["faces"], material=material)
            scene.add(pyrender.Mesh(primitives=[prim]), pose=q["pose"], name=q["name"])
        cam = job["camera"]
        scene.add(pyrender.PerspectiveCamera(yfov=cam["yfov"], znear=cam["znear"], zfar=cam["zfar"]),
                  pose=cam["pose"])
    flags = pyrender.RenderFlags.FLAT if job["flat"] else pyrender.RenderFlags.NONE
    color, depth = renderer.render(scene, flags=flags)
    out[name] = {"color": np.ascontiguousarray(color[..., :3]), "warnings": warned,
                 "transparent": sorted(str(n.name) for n in scene.mesh_nodes if n.mesh.is_transparent)}
renderer.delete()
with open(sys.argv[4], "wb") as f:
    pickle.dump(out, f)
"""


def camera() -> sr.PerspectiveCamera:
    return sr.PerspectiveCamera(fov_y=FOV_Y, width=W, height=H, near=NEAR, far=FAR).look_at(EYE, (0, 0, 0))


def quad(x0, x1, y0, y1, z_of_x=lambda x: 0.0 * x) -> tuple[np.ndarray, np.ndarray]:
    """A quad facing +z (counter-clockwise seen from the camera), z = z_of_x(x)."""
    xs = np.array([x0, x1, x1, x0], float)
    positions = np.c_[xs, [y0, y0, y1, y1], z_of_x(xs)]
    return positions, np.array([[0, 1, 2], [0, 2, 3]])


def translation(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


class Layer:
    """One quad: local positions, the node pose placing them, an RGBA colour, blended or not."""

    def __init__(self, name, positions, faces, pose, color, blend=True):
        self.name, self.positions, self.faces = name, positions, faces
        self.pose, self.color, self.blend = pose, tuple(color), blend

    def spec(self) -> dict:
        e1 = self.positions[1] - self.positions[0]
        e2 = self.positions[2] - self.positions[0]
        n = np.cross(e1, e2)
        return {"name": self.name, "positions": self.positions, "faces": self.faces,
                "normals": np.tile(n / np.linalg.norm(n), (len(self.positions), 1)),
                "pose": self.pose, "color": self.color, "blend": self.blend}

    def material(self) -> sr.Material:
        return sr.Material(base_color=self.color, metallic=0.0, roughness=1.0, double_sided=True,
                           model="pbr", name=self.name, alpha_mode="blend" if self.blend else "opaque")


def softrast_scene(layers) -> sr.Scene:
    scene = sr.Scene()
    for layer in layers:
        scene.add(sr.Mesh(layer.positions, layer.faces, material=layer.material()), pose=layer.pose)
    scene.add(sr.DirectionalLight())  # not read by unlit; to_pyrender warns about a scene without lights
    return scene


def render(layers, outputs=("color",), **options) -> sr.Frame:
    options = {"shading": "unlit", "srgb": False, "cull": "none", **options}
    return sr.Renderer(W, H).render(softrast_scene(layers), camera(), outputs=outputs, **options)


def pyrender_job(layers, flat=True, ambient=(0.0, 0.0, 0.0)) -> dict:
    cam = camera()
    return {"quads": [layer.spec() for layer in layers], "flat": flat, "ambient": list(ambient),
            "camera": {"yfov": math.radians(FOV_Y), "znear": NEAR, "zfar": FAR, "pose": cam.pose}}


def run_pyrender(tmp_path: pathlib.Path, jobs: dict) -> dict:
    # the child imports softrast (to_pyrender): it keeps the environment (test_from_pyrender.py)
    return run_pyrender_script(tmp_path, "blend_child", CHILD,
                               {"width": W, "height": H, "jobs": jobs}, timeout=300)


def composite(colors) -> np.ndarray:
    """Back-to-front "over" of RGBA colours (the first opaque), in whatever space they are given."""
    c = np.zeros(3)
    for rgba in colors:
        a = rgba[3]
        c = a * np.asarray(rgba[:3], float) + (1.0 - a) * c
    return c


def to_byte(c) -> np.ndarray:
    return np.floor(np.clip(np.asarray(c, float), 0.0, 1.0) * 255.0 + 0.5)


def coverage(layer: Layer) -> tuple[np.ndarray, np.ndarray]:
    """softrast's mask and depth of one quad drawn alone, opaque."""
    solid = Layer(layer.name, layer.positions, layer.faces, layer.pose, layer.color[:3] + (1.0,), blend=False)
    frame = render([solid], outputs=("mask", "depth"))
    return frame.mask.copy(), frame.depth.copy()


def interior(labels: np.ndarray) -> np.ndarray:
    """Pixels whose whole 5x5 neighbourhood has the same label (away from every edge)."""
    return ndimage.maximum_filter(labels, size=5) == ndimage.minimum_filter(labels, size=5)


def background_layer() -> Layer:
    return Layer("background", *quad(-6.0, 6.0, -5.0, 5.0), translation(z=-2.0), BACKGROUND, blend=False)


# -- three separate layers, each its own node ----------------------------------------------------

def separate_layers() -> list[Layer]:
    """Three translucent quads at z = -1, 0, 0.8, each its node's origin (so pyrender's sort by
    node distance is their depth order), overlapping on screen in every combination."""
    a = Layer("a", *quad(-1.0, 1.0, -1.0, 1.0), translation(-0.6, 0.0, -1.0), (0.9, 0.15, 0.1, 0.5))
    b = Layer("b", *quad(-1.0, 1.0, -1.0, 1.0), translation(0.6, 0.4, 0.0), (0.1, 0.7, 0.2, 0.5))
    c = Layer("c", *quad(-1.0, 1.0, -0.75, 0.75), translation(0.0, -0.55, 0.8), (0.15, 0.25, 0.9, 0.5))
    return [a, b, c]


@pytest.fixture(scope="module")
def separate(tmp_path_factory) -> dict:
    layers = [background_layer(), *separate_layers()]
    # pyrender's lit shader with ambient light 1 and no lights: colour = base colour, written as
    # pow(c, 1/2.2) and blended so
    jobs = {"flat": pyrender_job(layers), "lit": pyrender_job(layers, flat=False, ambient=(1.0, 1.0, 1.0)),
            "converted": {"softrast": (softrast_scene(layers), camera()), "flat": True}}
    return {"layers": layers, "pyrender": run_pyrender(tmp_path_factory.mktemp("blend_separate"), jobs)}


def region_model(layers, space=lambda c: c):
    """(labels, interior, expected): each pixel's set of layers (a bit per quad), the interior
    pixels, and the back-to-front composite of its layers (colours mapped by ``space``, alpha
    kept), per pixel."""
    masks = [coverage(layer)[0] for layer in layers]
    labels = sum(m.astype(np.int64) << k for k, m in enumerate(masks))
    expected = np.zeros((H, W, 3))
    for label in np.unique(labels):
        # the layers are given back to front (each quad lies wholly behind the next)
        stack = [tuple(space(np.asarray(layer.color[:3]))) + (layer.color[3],)
                 for k, layer in enumerate(layers) if label >> k & 1]
        expected[labels == label] = composite(stack)
    return labels, interior(labels) & masks[0], expected


def test_separate_layers_match_pyrender_flat(separate) -> None:
    """softrast's unlit, srgb=False colour is the exact composite (within 1/255) and pyrender's
    FLAT colour, built directly and through to_pyrender, is within 2/255 of it, on every region
    (the background alone, and 1, 2 or 3 layers over it)."""
    layers, pr = separate["layers"], separate["pyrender"]
    labels, inner, expected = region_model(layers)
    ours = render(layers).color.astype(np.int64)
    regions = np.unique(labels[inner])
    assert len(regions) == 8, regions  # the background with every subset of the three layers
    for label in regions:
        assert (inner & (labels == label)).sum() > 40, label
    np.testing.assert_array_less(np.abs(ours - to_byte(expected))[inner], MODEL_TOL + 1)
    assert pr["flat"]["transparent"] == ["a", "b", "c"]  # what pyrender sorts and blends
    for name in ("flat", "converted"):
        diff = np.abs(pr[name]["color"].astype(np.int64) - ours)[inner]
        assert diff.max() <= FLAT_TOL, (name, diff.max(), np.unravel_index(diff.argmax(), diff.shape))
    assert pr["converted"]["warnings"] == []
    assert sorted(pr["converted"]["transparent"]) == [f"softrast instance {k} (id {k})" for k in (1, 2, 3)]


def test_separate_layers_encoding_differs_by_design(separate) -> None:
    """softrast's default colour is the sRGB encoding of the linear-light composite (within
    1/255); pyrender's lit render blends its shader's pow(c, 1/2.2) outputs (within 2/255 of
    that model). The two models differ by up to 18/255 here where layers overlap: the
    difference is where blending happens, not an error in either."""
    layers, pr = separate["layers"], separate["pyrender"]
    labels, inner, linear = region_model(layers)
    ours = render(layers, srgb=True).color.astype(np.int64)
    np.testing.assert_array_less(np.abs(ours - to_byte(srgb_encode(linear)))[inner], MODEL_TOL + 1)
    _, _, gamma = region_model(layers, space=lambda c: c ** (1 / 2.2))
    lit = pr["lit"]["color"].astype(np.int64)
    assert np.abs(lit - to_byte(gamma))[inner].max() <= FLAT_TOL
    models = np.abs(to_byte(srgb_encode(linear)) - to_byte(gamma))[inner]
    assert models.max() >= 15, models.max()  # blending encoded values is visibly different
    assert np.abs(lit - ours)[inner].max() >= 15


# -- two interpenetrating layers -----------------------------------------------------------------

P_COLOR, Q_COLOR = (0.9, 0.2, 0.1, 0.5), (0.1, 0.3, 0.9, 0.5)


def crossing_layers(last: str | None) -> list[Layer]:
    """P in the plane z = 0, Q in z = 0.6 x (in front of P where x > 0), the same world geometry
    whatever ``last``: the quad named ``last`` gets its node origin at z = 1 (its vertices moved
    by -1), so pyrender, sorting by node distance, draws it last."""
    shapes = {"P": (quad(-1.2, 1.2, -0.9, 0.9), P_COLOR),
              "Q": (quad(-1.7, 1.7, -0.5, 0.5, lambda x: 0.6 * x), Q_COLOR)}
    layers = [background_layer()]
    for name, ((positions, faces), color) in shapes.items():
        lift = 1.0 if name == last else 0.0
        layers.append(Layer(name, positions - (0.0, 0.0, lift), faces, translation(z=lift), color))
    return layers


def test_interpenetrating_layers_pyrender_depends_on_node_order(tmp_path) -> None:
    """pyrender's image changes with which node it draws last; softrast's does not (byte for
    byte under either draw order; the same interior pixels under either node / vertex split),
    and is the exact composite in depth order on both sides of the intersection, where each of
    pyrender's images is right on one side only (the other side shows the last-drawn quad's
    region with one layer: the depth test dropped it)."""
    jobs = {f"{last}_last": pyrender_job(crossing_layers(last)) for last in ("P", "Q")}
    pr = run_pyrender(tmp_path, jobs)
    base = crossing_layers(None)
    bg, p, q = base
    p_mask, p_depth = coverage(p)
    q_mask, q_depth = coverage(q)
    q_front = q_mask & p_mask & (q_depth < p_depth)
    labels = p_mask.astype(np.int64) + 2 * q_mask + 4 * q_front
    inner = interior(labels)
    both_p_front, both_q_front = inner & (labels == 3), inner & (labels == 7)
    assert both_p_front.sum() > 400 and both_q_front.sum() > 400
    one_layer = inner & ((labels == 1) | (labels == 2))
    assert (inner & (labels == 1)).sum() > 400 and (inner & (labels == 2)).sum() > 400

    # softrast: order independent, and the exact composite
    frames = [render(layers).color.astype(np.int64)
              for layers in (base, [bg, q, p], crossing_layers("P"), crossing_layers("Q"))]
    np.testing.assert_array_equal(frames[0], frames[1])  # draw order: every pixel
    for other in frames[2:]:
        np.testing.assert_array_equal(frames[0][inner], other[inner])
    ours = frames[0]
    expected = np.zeros((H, W, 3))
    expected[labels == 0] = BACKGROUND[:3]
    expected[labels == 1] = composite([BACKGROUND, P_COLOR])
    expected[labels == 2] = composite([BACKGROUND, Q_COLOR])
    expected[labels == 3] = composite([BACKGROUND, Q_COLOR, P_COLOR])  # P in front
    expected[labels == 7] = composite([BACKGROUND, P_COLOR, Q_COLOR])  # Q in front
    np.testing.assert_array_less(np.abs(ours - to_byte(expected))[inner], MODEL_TOL + 1)

    # pyrender: right where the quad it draws last is in front, one layer short elsewhere
    dropped = {"P_last": (both_p_front, both_q_front, Q_COLOR),
               "Q_last": (both_q_front, both_p_front, P_COLOR)}
    for name, (right, wrong, front) in dropped.items():
        image = pr[name]["color"].astype(np.int64)
        assert np.abs(image - ours)[right | one_layer].max() <= FLAT_TOL, name
        only_front = to_byte(composite([BACKGROUND, front]))
        assert np.abs(image[wrong] - only_front).max() <= FLAT_TOL, name  # the other quad dropped
        assert np.abs(image - ours)[wrong].max(-1).min() >= 20, name  # every pixel visibly off
    changed = np.abs(pr["P_last"]["color"].astype(np.int64) - pr["Q_last"]["color"]).max(-1)
    assert (changed[both_p_front] >= 20).all() and (changed[both_q_front] >= 20).all()
