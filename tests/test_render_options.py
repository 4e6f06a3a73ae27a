"""RenderOptions: one frozen, checked, hashable object for every option of a render; render()'s
keywords override its fields and give the same bits."""
from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

import softrast as sr

from conftest import icosphere


def _scene():
    scene = sr.Scene()
    scene.add(icosphere(2), material=sr.Material(base_color=(0.8, 0.5, 0.2, 1.0), model="pbr"))
    light_pose = np.eye(4)
    light_pose[:3, 3] = (1.0, 2.0, 3.0)
    scene.add(sr.PointLight(color=(1.0, 1.0, 1.0), intensity=20.0), pose=light_pose)
    return scene


def _camera():
    cam = sr.PerspectiveCamera(fov_y=40.0)
    cam.pose = sr.look_at_pose((0.3, 0.4, 3.5), (0.0, 0.0, 0.0))
    return cam


def test_options_are_frozen_hashable_and_normalized():
    o = sr.RenderOptions(msaa=np.int64(4), background=[0.25, 0.5, 1], shadows=True, srgb=np.bool_(False))
    assert o.msaa == 4 and type(o.msaa) is int
    assert o.background == (0.25, 0.5, 1.0) and all(type(v) is float for v in o.background)
    assert o.shadows == "exact" and o.srgb is False
    assert hash(o) == hash(sr.RenderOptions(msaa=4, background=(0.25, 0.5, 1.0), shadows="exact", srgb=False))
    assert {o: 1}[o.replace()] == 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.msaa = 2
    assert pickle.loads(pickle.dumps(o)) == o


@pytest.mark.parametrize("field, value, error, text", [
    ("msaa", 3, ValueError, "msaa must be one of"),
    ("msaa", True, TypeError, "msaa must be an int"),
    ("ssaa", 9, ValueError, "ssaa must be in"),
    ("ambient", 1.5, ValueError, "ambient must be in"),
    ("background", (0.0, 2.0, 0.0), ValueError, "background"),
    ("cull", "sideways", ValueError, "cull"),
    ("shading", "toon", ValueError, "shading"),
    ("srgb", 1, TypeError, "srgb must be True or False"),
    ("shadows", "soft", ValueError, "shadows must be"),
    ("alpha_threshold", 2.0, ValueError, "alpha_threshold must be None or in"),
    ("line_width", 0.0, ValueError, "line_width must be"),
    ("texture_filter", "cubic", ValueError, "texture_filter"),
    ("raster", "dda", ValueError, "raster"),
])
def test_bad_options_raise_naming_the_field(field, value, error, text):
    with pytest.raises(error, match=text):
        sr.RenderOptions(**{field: value})
    with pytest.raises(error, match=text):  # the same through render's keywords
        sr.Renderer(8, 8).render(sr.Scene(), _camera(), "depth", **{field: value})


def test_unknown_keyword_and_wrong_options_type_raise():
    r = sr.Renderer(8, 8)
    with pytest.raises(TypeError, match="unexpected keyword argument 'msa'"):
        r.render(sr.Scene(), _camera(), "depth", msa=4)
    with pytest.raises(TypeError, match="options must be a softrast.RenderOptions"):
        r.render(sr.Scene(), _camera(), "depth", {"msaa": 4})


def test_cached_checks_tell_true_from_one():
    # Overrides are checked once per distinct value; True == 1 must not reuse 1's result.
    r = sr.Renderer(8, 8)
    r.render(sr.Scene(), _camera(), "depth", ssaa=1)
    with pytest.raises(TypeError, match="ssaa must be an int"):
        r.render(sr.Scene(), _camera(), "depth", ssaa=True)
    r.render(sr.Scene(), _camera(), "depth", background=(0, 0, 1))
    with pytest.raises(TypeError):
        r.render(sr.Scene(), _camera(), "depth", background=(False, False, True))


@pytest.mark.parametrize("opts", [
    dict(msaa=4, shading="blinn_phong", background=(0.1, 0.2, 0.3)),
    dict(ssaa=2, frequency="vertex", srgb=False, cull="none"),
    dict(wireframe=True, line_color=(1.0, 0.0, 0.0), normal_space="camera", raster="scanline"),
])
def test_options_object_keywords_and_overrides_give_the_same_bits(opts):
    scene, cam = _scene(), _camera()
    r = sr.Renderer(64, 48)
    outputs = ("color", "depth", "normal", "instance_id")
    by_keywords = r.render(scene, cam, outputs, **opts)
    options = sr.RenderOptions(**opts)
    by_object = r.render(scene, cam, outputs, options)
    # an object with other values, overridden back by keyword
    other = sr.RenderOptions(msaa=1, ssaa=1, shading="unlit", background=(1.0, 1.0, 1.0))
    base = other.replace(**{k: v for k, v in opts.items() if k in ("msaa", "ssaa")})
    rest = {k: v for k, v in opts.items() if k not in ("msaa", "ssaa")}
    rest.setdefault("shading", "auto")
    rest.setdefault("background", (0.0, 0.0, 0.0))
    overridden = r.render(scene, cam, outputs, base, **rest)
    for name in outputs:
        a = getattr(by_keywords, name)
        assert np.array_equal(a, getattr(by_object, name)), name
        assert np.array_equal(a, getattr(overridden, name)), name
    frames = list(r.render_many(scene, [cam, cam], outputs, options=options))
    for f in frames:
        for name in outputs:
            assert np.array_equal(getattr(f, name), getattr(by_object, name)), name


def _captured_core_call(r, scene, cam, outputs):
    """The draws and options dict render() hands the core, from a valid render."""
    captured = {}
    core = r._core

    class Spy:
        def render(self, draws, options):
            captured.update(draws=draws, options=dict(options))
            return core.render(draws, options)

        def __getattr__(self, name):
            return getattr(core, name)

    r._core = Spy()
    try:
        r.render(scene, cam, outputs)
    finally:
        r._core = core
    return core, captured["draws"], captured["options"]


@pytest.mark.parametrize("python_kw, core_change", [
    ({"ambient": 1.5}, {"ambient": 1.5}),
    ({"background": (0.0, 2.0, 0.0)}, {"background": (0.0, 2.0, 0.0)}),
    ({"msaa": 4, "ssaa": 2}, {"msaa": 4, "ssaa": 2}),
    ({"msaa": 3}, {"msaa": 3}),
    ({"ssaa": 9}, {"ssaa": 9}),
    ({"alpha_threshold": 2.0}, {"alpha_threshold": 2.0}),
    ({"outputs": ["bogus"]}, {"outputs": ["bogus"]}),
    ({"outputs": []}, {"outputs": []}),
])
def test_the_core_checks_in_pythons_words(python_kw, core_change):
    # The core checks again what RenderOptions guarantees (a caller of softrast._core directly
    # gets the same words); the texts agree up to the value quoted after "got".
    r, scene, cam = sr.Renderer(16, 16), _scene(), _camera()
    core, draws, options = _captured_core_call(r, scene, cam, ("color", "depth"))
    kw = dict(python_kw)
    outputs = kw.pop("outputs", ("color", "depth"))
    with pytest.raises((ValueError, TypeError)) as py_error:
        r.render(scene, cam, outputs, **kw)
    with pytest.raises(ValueError) as core_error:
        core.render(draws, {**options, **core_change})
    assert str(core_error.value).split(", got")[0] == str(py_error.value).split(", got")[0]
