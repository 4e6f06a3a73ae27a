"""softrast.report: its exact references (against closed forms and brute-force integration) and
`softrast report --quick` (files, the long-format CSV, errors that fall as the knobs rise).
No assertion is made on any time: the machine is shared and noisy."""
from __future__ import annotations

import csv
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import softrast as sr
from softrast import report
from softrast.cli import main


# ------------------------------------------------------------------------------- the references

@pytest.mark.parametrize("width, height, radius, centre", [
    (128, 128, report.sphere_radius_px(30.0, 128, 5.0), None),   # the report's sphere
    (64, 48, 20.3, None),
    (50, 50, 10.0, (20.25, 31.7)),                                 # off the pixel grid's symmetry
    (33, 33, 16.0, None),                                          # touches the image's edges
    (40, 30, 0.3, (7.9, 8.2)),                                     # inside one pixel
])
def test_disk_coverage_sums_to_pi_r2(width, height, radius, centre):
    cov = report.disk_coverage(width, height, radius, centre)
    assert cov.shape == (height, width) and cov.dtype == np.float64
    assert cov.min() >= 0.0 and cov.max() <= 1.0
    area = math.pi * radius ** 2
    assert abs(cov.sum() - area) <= 1e-9 * area, (cov.sum(), area)
    # Squares wholly inside the disk are exactly 1, wholly outside exactly 0.
    cx, cy = (width / 2.0, height / 2.0) if centre is None else centre
    j, i = np.meshgrid(np.arange(width), np.arange(height))
    corners = [np.hypot(j + dx - cx, i + dy - cy) for dx in (0, 1) for dy in (0, 1)]
    inside = np.max(corners, axis=0) <= radius
    assert (cov[inside] == 1.0).all()
    near = np.hypot(np.clip(cx, j, j + 1) - cx, np.clip(cy, i, i + 1) - cy)
    assert (cov[near >= radius] == 0.0).all()


def test_disk_coverage_matches_brute_force_on_edge_pixels():
    """A 2048 x 2048 grid of samples per pixel on edge pixels: the closed form is within the
    grid's own error (a few 1e-6)."""
    width = height = 64
    radius, centre = 23.7, (31.3, 32.9)
    cov = report.disk_coverage(width, height, radius, centre)
    rows, cols = np.nonzero((cov > 0.0) & (cov < 1.0))
    n = 2048
    o = (np.arange(n) + 0.5) / n
    for k in np.linspace(0, len(rows) - 1, 6).astype(int):
        i, j = rows[k], cols[k]
        x = j + o[None, :] - centre[0]
        y = i + o[:, None] - centre[1]
        estimate = np.mean(x * x + y * y <= radius * radius)
        assert abs(cov[i, j] - estimate) < 2e-5, (i, j, cov[i, j], estimate)


def test_sphere_hit_depth_normal_and_silhouette():
    """Odd image: the centre pixel's ray is the optical axis, so depth = distance - radius
    exactly; every hit lies on the sphere with the radial normal; the pixel centres hit are
    those inside the silhouette disk of sphere_radius_px."""
    size, fov, distance, radius = 33, 30.0, 5.0, 1.3
    depth, position, normal = report.sphere_hit(size, size, fov, distance, radius)
    c = size // 2
    assert depth[c, c] == pytest.approx(distance - radius, rel=1e-15, abs=0.0)
    np.testing.assert_allclose(normal[c, c], (0.0, 0.0, 1.0), atol=1e-15)
    hit = depth > 0.0
    np.testing.assert_allclose(np.linalg.norm(position[hit], axis=-1), radius, rtol=1e-13)
    np.testing.assert_allclose(normal[hit] * radius, position[hit], atol=1e-13)
    assert (position[hit][:, 2] > 0.0).all()  # the near side
    r_px = report.sphere_radius_px(fov, size, distance, radius)
    j, i = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    in_disk = np.hypot(j - size / 2.0, i - size / 2.0) <= r_px
    assert np.array_equal(hit, in_disk)
    # depth is along the viewing axis: distance - z of the hit point
    np.testing.assert_allclose(depth[hit], distance - position[hit][:, 2], rtol=1e-13)


def test_clamped_line_mean_closed_form():
    rng = np.random.default_rng(3)
    p = rng.uniform(-1.5, 2.5, 200)
    q = rng.uniform(-1.5, 2.5, 200)
    q[:5] = p[:5]  # constant lines
    s = (np.arange(50000) + 0.5) / 50000
    numeric = np.clip(p[:, None] + (q - p)[:, None] * s[None, :], 0.0, 1.0).mean(axis=1)
    np.testing.assert_allclose(report._clamped_line_mean(p, q), numeric, atol=1e-8)


def test_checker_box_filter_matches_supersampling():
    """The exact box filter against 16384 x 512 samples of the checker function per pixel (rows
    finer: near the horizon a pixel spans a dozen checks' rows, and v-lines are image rows), on
    pixels near the horizon (many checks per pixel) and near the camera (few)."""
    width, height = 96, 80
    plane = report.GrazingPlane()
    image, full = report.checker_box_filter(plane, width, height)
    rows, cols = np.nonzero(full)
    assert full.any() and not full.all()
    top = rows.min()
    left = cols[rows == top].min()  # the plane's side edges cut the top rows
    ox = (np.arange(512) + 0.5) / 512
    oy = (np.arange(16384) + 0.5) / 16384
    for i, j in [(top, left), (top, 48), (top + 1, 70), (top + 4, 20), (top + 12, 60), (height - 1, 3)]:
        assert full[i, j]
        estimate = 0.0
        for rows_of in np.split(oy, 8):
            uv = plane.uv(j + ox[None, :], i + rows_of[:, None], width, height)
            estimate += np.sum((np.floor(plane.checks * uv[..., 0]) + np.floor(plane.checks * uv[..., 1])) % 2)
        estimate /= ox.size * oy.size
        assert abs(image[i, j] - estimate) < 2e-4, (i, j, image[i, j], estimate)
    # Pixels inside one check are exactly 0 or 1; the image is exactly 0 off the full pixels.
    assert np.count_nonzero((image[full] == 0.0) | (image[full] == 1.0)) > 0.2 * full.sum()
    assert (image[~full] == 0.0).all()


def test_checker_texture_is_the_checker_function():
    """Texel centres of the texture the scene renders read the checker function there."""
    plane = report.GrazingPlane()
    tex = plane.texture_image()
    n = tex.shape[0]
    r, c = np.mgrid[0:n:7, 0:n:5]
    u, v = (c + 0.5) / n, 1.0 - (r + 0.5) / n
    expected = (np.floor(plane.checks * u) + np.floor(plane.checks * v)) % 2
    assert np.array_equal(tex[r, c, 0], expected.astype(np.float32))


@pytest.mark.parametrize("model", ["lambert", "phong", "blinn_phong", "pbr", "normal"])
def test_shading_closed_forms_are_the_renderers(model):
    """On a fine sphere, away from the silhouette, the renderer's radiance is the closed form
    ``report.shade`` computes at the exact hit (so the colour references are softrast's models)."""
    size = 96
    sphere = report._Sphere(size, size)
    frame = sr.Renderer(size, size).render(sphere.scene(7, model), sphere.camera, outputs=("radiance", "mask"))
    interior = sphere.coverage == 1.0
    interior[1:-1, 1:-1] &= (interior[:-2, 1:-1] & interior[2:, 1:-1] & interior[1:-1, :-2] & interior[1:-1, 2:])
    err = np.abs(frame.radiance[interior] - sphere.colour(model)[interior])
    assert err.max() < 2e-3, err.max()


def test_pareto_front():
    points = [(1.0, 5.0), (2.0, 3.0), (2.5, 4.0), (3.0, 3.0), (4.0, 1.0), (0.5, 9.0)]
    assert report.pareto_front(points) == [5, 0, 1, 4]


# ------------------------------------------------------------------------- softrast report --quick

@pytest.fixture(scope="module")
def quick_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    assert main(["report", "--quick", "--out", str(out)]) == 0
    with open(out / "report.csv", newline="") as f:
        reader = csv.DictReader(f)
        columns = reader.fieldnames
        rows = list(reader)
    return out, columns, rows


def _series(rows, knob, metric):
    """{value: error} of one knob's metric, values in the sweep's order."""
    return {r["value"]: float(r["error"]) for r in rows if r["knob"] == knob and r["metric"] == metric}


def test_quick_report_files(quick_report):
    out, columns, rows = quick_report
    assert columns[:5] == ["knob", "value", "metric", "error", "time_ms"]
    assert tuple(columns) == report.CSV_COLUMNS
    for name in ("report.csv", "report.md", "error_vs_time.png"):
        assert (out / name).stat().st_size > 0
    png = sr.imread(out / "error_vs_time.png")
    assert png.ndim == 3 and png.shape[0] > 400 and png.shape[1] > 600
    md = (out / "report.md").read_text()
    for heading in ("## tessellation", "## frequency", "## shading_model", "## threads",
                    "## texture_filter", "## max_anisotropy", "## Pareto fronts", "## What a scene pays for"):
        assert heading in md


def test_quick_report_csv_is_long_format(quick_report):
    _, _, rows = quick_report
    keys = [(r["knob"], r["value"], r["metric"]) for r in rows]
    assert len(keys) == len(set(keys)), "one row per (knob, value, metric)"
    knobs = {r["knob"] for r in rows}
    assert knobs == {"tessellation", "frequency", "shading_model", "threads", "texture_filter", "max_anisotropy",
                     "msaa", "ssaa", "shadow_resolution"}
    for knob in knobs:
        values = {k[1] for k in keys if k[0] == knob}
        metrics = {k[2] for k in keys if k[0] == knob}
        assert len(values) >= 2
        assert {(knob, v, m) for v in values for m in metrics} <= set(keys), f"{knob}: every value has every metric"
    assert {v for k, v, _ in keys if k == "tessellation"} == {str(k) for k in report.QUICK.subdivisions}
    assert {v for k, v, _ in keys if k == "texture_filter"} == set(sr.texture.FILTERS)
    for r in rows:
        # every cell holds a number (times are measurements only: nothing is asserted about them)
        assert all(math.isfinite(float(r[k])) for k in ("error", "time_ms", "time_spread_ms"))
        assert r["scene"] in ("sphere", "checker")
        assert r["reference"] and r["better"] in ("lower", "higher")
    # The one reference that is a render says so.
    labelled = {r["reference"] for r in rows if r["metric"] == "rmse_box"}
    assert len(labelled) == 1 and labelled.pop().startswith("render_16x16_supersampled")
    assert all("supersampled" not in r["reference"] for r in rows if r["metric"] != "rmse_box")


def _never_rises(series, rel=0.02, abs_=1e-12):
    """Each error at most the previous one plus a small noise allowance."""
    errors = list(series.values())
    return all(b <= a * (1.0 + rel) + abs_ for a, b in zip(errors, errors[1:])), series


@pytest.mark.parametrize("metric, drop", [
    ("coverage_mean", 3.0),    # falls to the point-sampling floor (~0.2 of an edge pixel)
    ("depth_mean", 1000.0),
    ("normal_mean_deg", 1000.0),
    ("rmse", 1000.0),
    ("rmse_box", 3.0),         # falls to the aliasing floor: what msaa / ssaa will lower
])
def test_tessellation_errors_fall(quick_report, metric, drop):
    _, _, rows = quick_report
    series = _series(rows, "tessellation", metric)
    assert _never_rises(series)
    errors = list(series.values())
    assert errors[-1] * drop < errors[0], series


def test_tessellation_geometry_converges(quick_report):
    """Silhouettes of the finer spheres cover exactly the pixel centres inside the exact disk,
    and the depth error is far below the coarsest sphere's."""
    _, _, rows = quick_report
    mismatch = _series(rows, "tessellation", "mask_mismatch_px")
    assert mismatch[str(report.QUICK.subdivisions[-1])] == 0.0
    assert mismatch[str(report.QUICK.subdivisions[0])] > 100
    depth_max = list(_series(rows, "tessellation", "depth_max").values())
    assert depth_max[-1] * 100 < depth_max[0]


def test_psnr_and_ssim_rise_with_tessellation(quick_report):
    _, _, rows = quick_report
    psnr = list(_series(rows, "tessellation", "psnr_db").values())
    assert all(b >= a - 0.5 for a, b in zip(psnr, psnr[1:])), psnr
    assert psnr[-1] > psnr[0] + 40.0, psnr
    ssim = list(_series(rows, "tessellation", "ssim").values())
    assert all(b >= a - 1e-3 for a, b in zip(ssim, ssim[1:])), ssim
    assert ssim[-1] > 0.999


def test_texture_errors_order(quick_report):
    """Against the exact box filter of the grazing checkerboard: anisotropic < trilinear <
    bilinear < nearest, more anisotropic probes never worse, and one probe is trilinear."""
    _, _, rows = quick_report
    rmse = _series(rows, "texture_filter", "rmse")
    assert rmse["anisotropic"] < rmse["trilinear"] < rmse["bilinear"] < rmse["nearest"], rmse
    assert rmse["anisotropic"] < 0.6 * rmse["trilinear"], rmse  # measured: 0.52 at 128x128
    ssim = _series(rows, "texture_filter", "ssim")
    assert ssim["anisotropic"] > ssim["trilinear"], ssim  # (nearest's aliasing can score high)
    aniso = _series(rows, "max_anisotropy", "rmse")
    assert _never_rises(aniso)
    assert aniso["16"] < aniso["1"]
    assert aniso["1"] == pytest.approx(rmse["trilinear"], rel=1e-12)
    assert aniso["16"] == pytest.approx(rmse["anisotropic"], rel=1e-12)


def test_frequency_and_threads(quick_report):
    """Per-pixel shading is the most accurate frequency; thread counts give identical images."""
    _, _, rows = quick_report
    rmse = _series(rows, "frequency", "rmse")
    assert rmse["pixel"] <= rmse["vertex"] <= rmse["face"], rmse
    ssim = _series(rows, "frequency", "ssim")
    assert ssim["pixel"] >= ssim["vertex"] >= ssim["face"], ssim
    threads = [r for r in rows if r["knob"] == "threads"]
    assert len({r["error"] for r in threads}) == 1
    assert all("image identical to threads=1" in r["setting"] for r in threads)


# ------------------------------------------------------------------------- optional dependencies

@pytest.mark.parametrize("knob, values", [("msaa", ("1", "2", "4", "8", "16")), ("ssaa", ("1", "2", "3", "4"))])
def test_antialiasing_errors_fall(quick_report, knob, values):
    # More samples per pixel: the coverage error against the exact disk area and the colour
    # error against the box filter fall at every step (stratified samples on a smooth edge).
    _, _, rows = quick_report
    for metric in ("coverage_mean", "rmse_box"):
        series = _series(rows, knob, metric)
        assert tuple(series) == values
        errors = [series[v] for v in values]
        assert all(b < a for a, b in zip(errors, errors[1:])), (metric, series)
    # Point sampling (1) against 16 msaa samples / 4x4 ssaa: several times lower.
    cov = _series(rows, knob, "coverage_mean")
    assert cov[values[-1]] < cov["1"] / 3


def test_shadow_map_errors_fall_with_resolution(quick_report):
    # Shadow maps against the exact method on the sphere casting onto a backdrop: each doubling
    # of the resolution lowers both errors; the finest map misplaces under 0.2% of the pixels.
    _, _, rows = quick_report
    values = tuple(str(r) for r in report.QUICK.shadow_resolutions) + ("exact",)
    for metric in ("rmse", "shadow_mismatch"):
        series = _series(rows, "shadow_resolution", metric)
        assert tuple(series) == values
        errors = [series[v] for v in values[:-1]]
        assert all(b < a for a, b in zip(errors, errors[1:])), (metric, series)
        assert series["exact"] == 0.0
    assert _series(rows, "shadow_resolution", "shadow_mismatch")[values[-2]] < 0.002


def test_softrast_imports_without_the_report_dependencies():
    code = ("import sys; sys.modules['matplotlib'] = None; sys.modules['skimage'] = None; "
            "import softrast, softrast.report, softrast.cli; print('ok')")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr


def test_missing_dependency_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib now raises ImportError
    out = tmp_path / "never"
    assert main(["report", "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error: ") and err.count("\n") == 1, err
    assert "matplotlib" in err and "pip install softrast[report]" in err
    assert not out.exists()  # checked before anything is measured or written


def test_report_requires_out(capsys):
    assert main(["report", "--quick"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error: ") and "--out" in err


def _never_measure(*args, **kwargs):
    raise AssertionError("measured before checking the output folder")


def test_out_under_a_file_is_an_error_before_measuring(tmp_path, monkeypatch, capsys):
    """--out that cannot be created: a one-line error naming the folder, nothing measured."""
    from softrast import report

    monkeypatch.setattr(report, "measure", _never_measure)
    (tmp_path / "file.txt").write_text("x")
    out = tmp_path / "file.txt" / "sub"
    assert main(["report", "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error: ") and err.count("\n") == 1, err
    assert str(out) in err and "report folder" in err
    with pytest.raises(OSError, match="report folder"):
        report.run(out, quick=True)


def test_out_not_writable_is_an_error_before_measuring(tmp_path, monkeypatch, capsys):
    """A folder where no file can be created (read-only; simulated: tests run as root, for whom
    chmod does not stop writes): a one-line error naming the folder, before measuring."""
    import builtins

    from softrast import report

    out = tmp_path / "readonly"
    out.mkdir()
    real_open = builtins.open

    def read_only_open(file, mode="r", *args, **kwargs):
        if os.path.dirname(os.path.abspath(os.fspath(file))) == str(out) and set(mode) & set("wxa+"):
            raise PermissionError(13, "Permission denied", os.fspath(file))
        return real_open(file, mode, *args, **kwargs)

    real_os_open = os.open

    def read_only_os_open(file, flags, *args, **kwargs):
        if os.path.dirname(os.path.abspath(os.fspath(file))) == str(out) and \
                flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
            raise PermissionError(13, "Permission denied", os.fspath(file))
        return real_os_open(file, flags, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", read_only_open)
    monkeypatch.setattr(os, "open", read_only_os_open)
    monkeypatch.setattr(report, "measure", _never_measure)
    assert main(["report", "--quick", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("softrast: error: ") and err.count("\n") == 1, err
    assert str(out) in err and "not writable" in err
    assert os.listdir(out) == []
