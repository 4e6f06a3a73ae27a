"""The ``softrast`` command's argument parsing: the parser of every subcommand, the argument
types that check each value, and ``CliError`` (a user error: one line on stderr, exit 2)."""
from __future__ import annotations

import argparse
import math

from .. import _core
from .._version import __version__
from ..frame import _SAVE_FORMATS
from ..render import _SHADING


class CliError(Exception):
    """A user error: reported as one line on stderr, exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise CliError(message)  # argparse would print the usage block and sys.exit(2)


def _size(text: str) -> tuple[int, int]:
    parts = text.lower().split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}") from None
    if w <= 0 or h <= 0:
        raise argparse.ArgumentTypeError(f"width and height must be positive, got {text!r}")
    return w, h


def _vec3(text: str) -> tuple[float, float, float]:
    try:
        x, y, z = (float(p) for p in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers x,y,z, got {text!r}") from None
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise argparse.ArgumentTypeError(f"coordinates must be finite, got {text!r}")
    return x, y, z


def _rgb(text: str) -> tuple[float, float, float]:
    """r,g,b in [0, 1] (linear, as Material and render's colours)."""
    try:
        rgb = tuple(float(p) for p in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers r,g,b, got {text!r}") from None
    if len(rgb) != 3 or not all(0.0 <= v <= 1.0 for v in rgb):
        raise argparse.ArgumentTypeError(f"expected three numbers in [0, 1] as r,g,b, got {text!r}")
    return rgb


def _positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v) or v <= 0.0:
        raise argparse.ArgumentTypeError(f"must be positive and finite, got {text!r}")
    return v


def _int_at_least(minimum: int, note: str = ""):
    """An argparse type: an integer >= minimum."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum}{note}, got {text!r}")
        return v
    return parse


_threads = _int_at_least(0, " (0 = one per core)")
_count = _int_at_least(1)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="softrast", description="softrast: a CPU software rasterizer.")
    parser.add_argument("--version", action="version", version=f"softrast {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("render", help="render a mesh file to images",
                       description="Render a mesh file (OBJ, PLY, STL, GLB, ...) to image files.")
    r.add_argument("mesh", metavar="MESH", help="mesh file loaded with trimesh")
    r.add_argument("-o", "--output", required=True, metavar="COLOR",
                   help="colour image, (h, w, 3) uint8 (.png, .jpg, .tif, ...)")
    r.add_argument("--size", type=_size, default=(640, 480), metavar="WxH", help="image size (default 640x480)")
    r.add_argument("--depth", metavar="PATH", help="depth along the view axis, float32 (.exr or .tif); 0 = background")
    r.add_argument("--mask", metavar="PATH", help="coverage mask, 0/255 uint8 (.png)")
    r.add_argument("--normal", metavar="PATH", help="world-space unit normals, float32 (.exr or .tif)")
    r.add_argument("--eye", type=_vec3, metavar="x,y,z", help="camera position (default: frames the mesh)")
    r.add_argument("--target", type=_vec3, metavar="x,y,z", help="point looked at (default: bounds centre)")
    r.add_argument("--up-axis", choices=("y", "z"), default="y",
                   help="the file's up axis: z maps (x, y, z) to (x, z, -y) on loading (default y)")
    r.add_argument("--up", type=_vec3, default=(0.0, 1.0, 0.0), metavar="x,y,z", help="up direction (default 0,1,0)")
    r.add_argument("--fov", type=float, default=45.0, help="vertical field of view in degrees (default 45)")
    r.add_argument("--near", type=_positive_float, help="near plane distance (default: from the mesh size)")
    r.add_argument("--far", type=_positive_float, help="far plane distance (default: from the mesh size)")
    r.add_argument("--cull", choices=("back", "none", "front"), default="back", help="face culling (default back)")
    r.add_argument("--shading", choices=_SHADING, default="auto",
                   help="shading model (default auto: each material's own, lambert without one)")
    r.add_argument("--frequency", choices=_core.FREQUENCIES, default="pixel",
                   help="where lighting is evaluated (default pixel)")
    r.add_argument("--linear", action="store_true",
                   help="write linear colour values (default: sRGB-encoded, as viewers expect)")
    r.add_argument("--threads", type=_threads, default=0, help="worker threads, 0 = one per core (default)")
    r.add_argument("--texture", metavar="IMAGE",
                   help="base colour texture (sRGB) sampled at the mesh's uvs; replaces the file's")
    r.add_argument("--texture-filter", choices=_core.TEXTURE_FILTERS, default=None,
                   help="one filter for every texture (default: each texture's own, trilinear)")
    r.add_argument("--wireframe", action="store_true",
                   help="draw the mesh's edges over it (front edges shown, back ones hidden)")
    r.add_argument("--line-color", type=_rgb, default=(0.0, 0.0, 0.0), metavar="r,g,b",
                   help="--wireframe's colour, linear, in [0, 1] (default 0,0,0)")
    r.add_argument("--line-width", type=_positive_float, default=1.0, metavar="PX",
                   help="--wireframe's width in pixels (default 1)")
    aa = r.add_mutually_exclusive_group()
    aa.add_argument("--msaa", type=int, choices=(1, 2, 4, 8, 16), default=1,
                    help="multisample anti-aliasing: samples per pixel (default 1: off)")
    aa.add_argument("--ssaa", type=int, choices=range(1, 9), default=1, metavar="K",
                    help="supersampling: a KxK grid of shaded samples per pixel, K in 1..8 (default 1)")

    b = sub.add_parser("batch", help="render many views of mesh files into a dataset",
                       description="Render views of each mesh file into DIR/<mesh stem>/: one file "
                       "per output and view ({view:06d}_{output}.{ext}, as Frame.save writes) and a "
                       "cameras.json (K in OpenCV's convention, poses in OpenCV and OpenGL axes); "
                       "with --store zarr, one compressed array per output in views.zarr instead "
                       "of the files. A rerun skips the views whose files are all there.")
    b.add_argument("meshes", nargs="+", metavar="MESH", help="mesh files (OBJ, PLY, GLB, ...)")
    b.add_argument("--out", required=True, metavar="DIR", help="dataset directory (created if missing)")
    b.add_argument("--views", type=_count, default=24, metavar="N", help="views per mesh (default 24)")
    where = b.add_mutually_exclusive_group()
    where.add_argument("--orbit", type=_elevation, default=None, metavar="ELEVATION",
                       help="a turntable at this elevation in degrees (the default, at 20)")
    where.add_argument("--sphere", action="store_true", help="views spread evenly over a sphere")
    where.add_argument("--poses", metavar="FILE", help="camera-to-world poses (OpenGL axes): an "
                       "(n, 4, 4) .npy, or a cameras.json; --views is then their number")
    b.add_argument("--intrinsics", metavar="K.npy", help="a (3, 3) OpenCV K for every view (default: --fov)")
    b.add_argument("--outputs", type=_outputs, default=("color", "depth", "instance_id"),
                   metavar="NAMES", help="comma-separated outputs (default color,depth,instance_id)")
    b.add_argument("--formats", type=_formats, default={}, metavar="NAME=FMT,...",
                   help="file formats by output, e.g. depth=npy,color=jpg (default: Frame.save's)")
    b.add_argument("--size", type=_size, default=(640, 480), metavar="WxH", help="image size (default 640x480)")
    b.add_argument("--fov", type=float, default=45.0, help="vertical field of view in degrees (default 45)")
    b.add_argument("--workers", type=_threads, default=0, help="render threads, 0 = one per core (default)")
    b.add_argument("--no-resume", action="store_true", help="render every view, even those already written")
    b.add_argument("--store", choices=("files", "zarr"), default="files",
                   help="files: a file per output and view (default); zarr: one chunked, "
                   "compressed array per output in DIR/<mesh stem>/views.zarr, a view a chunk "
                   "(pip install softrast[zarr])")
    b.add_argument("--up-axis", choices=("y", "z"), default="y", help="the files' up axis (default y)")

    rp = sub.add_parser("report", help="measure error against run time for each quality knob",
                        description="Sweep each quality knob (tessellation, shading frequency and "
                        "model, threads, texture filter, max_anisotropy) on reference scenes with exact "
                        "references, and write DIR/report.csv (long format), DIR/report.md and "
                        "DIR/error_vs_time.png. Needs matplotlib and scikit-image "
                        "(pip install softrast[report]).")
    rp.add_argument("--out", required=True, metavar="DIR", help="report directory (created if missing)")
    rp.add_argument("--quick", action="store_true",
                    help="fewer knob values and repetitions on 128x128 images: under a minute (CI)")
    return parser


def _elevation(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected degrees, got {text!r}") from None
    if not -90.0 <= v <= 90.0:
        raise argparse.ArgumentTypeError(f"must be in [-90, 90] degrees, got {text!r}")
    return v


def _outputs(text: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    bad = [n for n in names if n not in _core.OUTPUTS]
    if not names or bad:
        raise argparse.ArgumentTypeError(f"unknown output {bad[0] if bad else text!r}; choose from "
                                         f"{','.join(_core.OUTPUTS)}")
    return names


def _formats(text: str) -> dict[str, str]:
    out = {}
    for item in (t.strip() for t in text.split(",") if t.strip()):
        name, _, fmt = item.partition("=")
        if name not in _SAVE_FORMATS or fmt not in _SAVE_FORMATS[name]:
            raise argparse.ArgumentTypeError(
                f"{item!r}: expected OUTPUT=FORMAT with a format of that output "
                f"({name}: {'/'.join(_SAVE_FORMATS.get(name, ())) or 'no such output'})")
        out[name] = fmt
    return out
