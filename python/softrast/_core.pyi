"""Type stub for the private compiled module ``softrast._core`` (cpp/bindings.cpp).

Users do not call this module directly: ``softrast.Renderer`` and ``softrast.Mesh`` wrap it.

Conventions shared with the Python layer
----------------------------------------
* view space is OpenGL's: x right, y up, the camera looks down -z.
* ``proj`` maps view space to clip space; NDC = clip.xyz / clip.w with x right, y up.
* window (pixel) space: x_win = (ndc_x + 1) / 2 * width, y_win = (1 - ndc_y) / 2 * height,
  so row 0 is the top of the image and the centre of pixel (row i, col j) is (j + 0.5, i + 0.5).
* depth output = distance along the camera's viewing axis (-z_view) in scene units; 0 = background.
"""
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt

SUBPIXEL_BITS: int  # fixed-point precision of snapped window coordinates (8 => 1/256 px)
TILE_SIZE_PX: int  # side of the square screen tiles owned by one thread at a time
MAX_IMAGE_SIDE: int  # largest width or height accepted
MAX_FRAMEBUFFER_BYTES: int  # refuse a render whose requested outputs need more than this
MAX_THREADS: int  # largest thread count a Renderer accepts (256)
OUTPUTS: tuple[str, ...]  # every output name render() accepts, in the output table's order
# The output table (cpp/framebuffer.hpp), one dict per output: name, dtype (numpy.dtype),
# channels (1 => (h, w), else (h, w, channels)), bytes_per_pixel, background (value where
# nothing is drawn; colour uses the render's background), pass ("resolve" | "shade"), doc.
OUTPUT_TABLE: tuple[dict[str, Any], ...]
SHADING_MODELS: tuple[str, ...]  # the core's models, from cpp/shade_models.hpp's model list ("lit":
                                 # render.py maps lambert/phong/blinn_phong/pbr/auto to it)
REFLECTANCE_MODELS: tuple[str, ...]  # a material record's model index names (cpp/lighting.hpp, Brdf)
FREQUENCIES: tuple[str, ...]  # "pixel", "vertex", "face"
CULL_MODES: tuple[str, ...]  # "none", "back", "front"
SHADING_PATHS: tuple[str, ...]  # "auto", "forward", "deferred"
RASTER_ALGORITHMS: tuple[str, ...]  # "edge", "scanline"
LINE_ALGORITHMS: tuple[str, ...]  # "bresenham", "dda"

class MeshData:
    """Geometry uploaded once and validated.

    Arrays that are C-contiguous, aligned and immutable (read-only views of a bytes object, as
    ``softrast.Mesh`` stores them) are viewed in place and kept alive; any other array is copied,
    so that no later write to it can reach the validated mesh.

    positions : (n, 3) float32, C-contiguous, finite
    faces     : (m, 3) int32, every index in [0, n)
    normals   : (n, 3) float32 or None (per-vertex; None => flat face normals when lit)
    colors    : (n, 4) float32 in [0, 1] or None (per-vertex RGBA)
    uvs       : (n, 2) float32 or None (kept for the texture stage)
    """

    def __init__(
        self,
        positions: npt.NDArray[np.float32],
        faces: npt.NDArray[np.int32],
        normals: npt.NDArray[np.float32] | None = None,
        colors: npt.NDArray[np.float32] | None = None,
        uvs: npt.NDArray[np.float32] | None = None,
    ) -> None: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_faces(self) -> int: ...

def _distortion_resolve(valid: Any, nearest: Any, corner: Any, directions: Any, view_width: int, view_size: int,
                        sample_to_normalized: Any, triangle_id: Any, instance_id: Any, instances: list,
                        camera_to_world: Any, centre: Any, surface: bool, threads: int) -> dict:
    """Lens distortion (python/softrast/distortion.py): per output pixel, the view sample it takes
    ("sample", "covered") and, with surface, its point on its own ray ("depth", "ray_depth",
    "position", "barycentric", float64)."""
def _distortion_bilinear(valid: Any, nearest: Any, corner: Any, directions: Any, view_width: int,
                         view_size: int, weights: Any, src: Any, out: Any) -> None:
    """out[p] = the bilinear interpolation of the view output src at pixel p's ray."""
def _fail_thread_start(n: int) -> None:
    """Testing only: the n-th worker thread started from now on fails (0 = off)."""

def _parked_threads() -> int:
    """Testing only: threads parked for good after a render ended during interpreter exit."""

class Renderer:
    def __init__(self, width: int, height: int, threads: int = 0, simd: bool = True) -> None:
        """threads = 0 => one worker per hardware core (at most MAX_THREADS); simd = False =>
        generic kernels. ValueError for threads outside [0, MAX_THREADS]; RuntimeError naming
        ``threads`` when the system refuses a worker thread (none is left running)."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def threads(self) -> int: ...
    @property
    def isa(self) -> str: ...
    def render(
        self,
        draws: Sequence[tuple[MeshData, npt.NDArray[np.float64], int, Sequence[float], tuple[Any, ...]]],
        spec: dict[str, Any],
    ) -> dict[str, np.ndarray]:
        """Render ``draws`` = [(mesh, model (4, 4) float64 model-to-world, instance_id, rgba,
        material)], material = (REFLECTANCE_MODELS index, kd_is_base, ka_is_kd, double_sided, ka,
        kd, ks, shininess, metallic, roughness, emissive) (softrast.Material._core).

        ``spec`` holds every option, checked by softrast.Renderer.render beforehand (the core
        re-checks only memory and what it needs for safety):
          view, proj : (4, 4) float64 world-to-view and view-to-clip
          orthographic : bool; near, far : float
          outputs : names from OUTPUTS (OUTPUT_TABLE gives each one's dtype and shape); only
                    these buffers are allocated and written
          cull : one of CULL_MODES; shading : one of SHADING_MODELS;
          shading_path : one of SHADING_PATHS; raster : one of RASTER_ALGORITHMS
          primitives (optional) : [(points, positions (n, 3) float32, segments (m, 2) int32 or
                   None, colors (n, 3) float32 or None, rgb, width or size, pose, instance_id)],
                   lines and points (softrast.Lines / Points); their arrays are viewed, not
                   copied, for the render; line_algorithm (optional) : one of LINE_ALGORITHMS
          background : 3 floats in [0, 1]; ambient : float in [0, 1]
          lights : [(kind 0/1/2 = directional/point/spot, radiance rgb, position, direction of
                   travel (unit), inverse_square, cone scale, cone offset)], world space
                   (softrast.Light._core); read by the "lit" model
          ambient_light : 3 floats; frequency : one of FREQUENCIES; srgb : bool
          texture_filter : index into TEXTURE_FILTERS, or -1 (each texture's own)
          normal_rotation : None (normals in world space) or 3 rows of 3 floats, world -> camera
          out : dict of arrays to write into (exact dtype and shape, C-contiguous, writeable),
                returned as they are, or None
        Each other array views C++ memory owned by its ``base`` (no copy). The GIL is released.
        """
