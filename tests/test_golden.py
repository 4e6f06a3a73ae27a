"""Every output of the golden scenes (tests/support/golden.py) is bit-identical to the recorded hashes.

The hashes were recorded from the commit named in tests/data/golden_hashes.json, before the core
was split along its seams; each scene is checked on both instruction sets and with 1,
2 and 3 threads. A difference here means a change altered rendered bits: if that is intended
(a new feature changing an existing output), say so in the commit and re-record with
`python3 tests/support/golden.py --write <commit>`.

The feature scenes (tests/support/golden_features.py: lights and materials, every shading model and
frequency, textures, every output, anti-aliasing, lines and points, lens distortion) are checked
the same way against tests/data/golden_features.json, recorded from commit 9c24f39; re-record
them with `python3 tests/support/golden_features.py --write <commit>`, under the same rule.
"""
from __future__ import annotations

import json

import pytest

from support import golden
from support import golden_features

WANT = json.loads(golden.HASHES.read_text())["scenes"]
MESHES = golden._meshes()
FEATURES_WANT = json.loads(golden_features.HASHES.read_text())["scenes"]
FEATURE_MESHES = golden_features.meshes()


def test_every_scene_is_recorded():
    assert sorted(WANT) == sorted(golden.SCENES)


@pytest.mark.parametrize("simd, threads", golden.CONFIGS, ids=lambda v: str(v))
@pytest.mark.parametrize("name", sorted(golden.SCENES))
def test_outputs_are_bit_identical_to_the_recorded_commit(name, simd, threads):
    got = golden.render_hashes(name, simd, threads, MESHES)
    assert sorted(got) == sorted(WANT[name])
    differ = [k for k in got if got[k] != WANT[name][k]]
    assert not differ, f"{name}: outputs {differ} differ from the recorded bits"


def test_every_feature_scene_is_recorded():
    assert sorted(FEATURES_WANT) == sorted(golden_features.SCENES)


def test_feature_scenes_cover_every_option():
    """The feature scenes keep exercising every value of the options they were made to cover."""
    options = [o for _, _, _, o in golden_features.SCENES.values()]

    def values(key, default):
        return {o.get(key, default) for o in options}

    assert values("shading", "auto") >= {"auto", "unlit", "lambert", "phong", "blinn_phong", "pbr",
                                         "normal", "uv"}
    assert values("frequency", "pixel") >= {"pixel", "vertex", "face"}
    assert values("srgb", True) >= {True, False}
    assert values("shading_path", "auto") >= {"auto", "forward", "deferred"}
    assert values("raster", "edge") >= {"edge", "scanline"}
    assert values("msaa", 1) >= {1, 2, 4, 8, 16}
    assert values("ssaa", 1) >= {1, 2, 3}
    assert values("line_algorithm", "bresenham") >= {"bresenham", "dda"}
    assert values("normal_space", "world") >= {"world", "camera"}
    assert values("texture_filter", None) >= {None, "nearest", "anisotropic"}
    assert values("cull", "back") >= {"back", "none", "front"}
    assert values("wireframe", False) >= {True, False}
    recorded = {k for scene in FEATURES_WANT.values() for k in scene}
    assert recorded == set(golden_features.OUTPUTS)


@pytest.mark.parametrize("simd, threads", golden_features.CONFIGS, ids=lambda v: str(v))
@pytest.mark.parametrize("name", sorted(golden_features.SCENES))
def test_feature_outputs_are_bit_identical_to_the_recorded_commit(name, simd, threads):
    got = golden_features.render_hashes(name, simd, threads, FEATURE_MESHES)
    assert sorted(got) == sorted(FEATURES_WANT[name])
    differ = [k for k in got if got[k] != FEATURES_WANT[name][k]]
    assert not differ, f"{name}: outputs {differ} differ from the recorded bits"


@pytest.mark.parametrize("simd", [True, False], ids=["simd", "generic"])
@pytest.mark.parametrize("name", sorted(golden_features.SCENES))
def test_the_lit_kernel_gives_the_plain_kernels_bits(name, simd):
    # The plain kernels (the headlight's Lambert, unlit, the normal as a colour) are a
    # specialisation of the lit kernel, which shades the same draws with the same formulas: forced
    # through it (the core's lit_kernel option), every scene keeps its recorded bits.
    got = golden_features.render_hashes(name, simd, 2, FEATURE_MESHES, lit_kernel=True)
    differ = [k for k in got if got[k] != FEATURES_WANT[name][k]]
    assert not differ, f"{name}: outputs {differ} differ through the lit kernel"
