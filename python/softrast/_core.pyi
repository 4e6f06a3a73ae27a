"""Type stub for the private compiled module ``softrast._core`` (cpp/bind/).

Written by ``python -m softrast._stubgen`` from the module itself (signatures as pybind11 3.1.0
spells them): do not edit.
Users do not call this module directly: ``softrast.Renderer`` and ``softrast.Mesh`` wrap it.

Conventions shared with the Python layer
----------------------------------------
* view space is OpenGL's: x right, y up, the camera looks down -z.
* ``proj`` maps view space to clip space; NDC = clip.xyz / clip.w with x right, y up.
* window (pixel) space: x_win = (ndc_x + 1) / 2 * width, y_win = (1 - ndc_y) / 2 * height,
  so row 0 is the top of the image and the centre of pixel (row i, col j) is (j + 0.5, i + 0.5).
* depth output = distance along the camera's viewing axis (-z_view) in scene units; 0 = background.
"""
import collections.abc
import typing
from typing import Any, TypedDict

import numpy
import numpy.typing

CONSTANT_DOCS: dict[str, Any]  # constant name -> its doc (the comments here)
CULL_MODES: tuple[str, ...]  # cull=
FREQUENCIES: tuple[str, ...]  # frequency=
LIGHT_KINDS: tuple[str, ...]  # Light.kind
LINE_ALGORITHMS: tuple[str, ...]  # line_algorithm=
MAX_FRAMEBUFFER_BYTES: int  # a render whose requested outputs need more than this is refused
MAX_IMAGE_SIDE: int  # largest width or height accepted
MAX_THREADS: int  # largest thread count a Renderer accepts
NORMAL_KINDS: tuple[str, ...]  # normal_kind=
OUTPUTS: tuple[str, ...]  # every output name a render accepts, in the output table's order
OUTPUT_TABLE: tuple[dict[str, Any], ...]  # one dict per output (cpp/framebuffer.hpp): name, dtype, channels (1 => (h, w), else (h, w, channels)), bytes_per_pixel, background, pass, doc
RASTER_ALGORITHMS: tuple[str, ...]  # raster=
RECORDS: dict[str, Any]  # record name -> its fields: (name, type, doc) tuples, in order
REFLECTANCE_MODELS: tuple[str, ...]  # a material's models (Material.model)
RENDER_OPTIONS: Any  # a render's options: (name, type, required, doc) tuples (RenderOptions)
SHADING_MODELS: tuple[str, ...]  # render(shading=): 'auto' (each material's model) or one model for every draw
SHADING_PATHS: tuple[str, ...]  # shading_path=
SHADOW_METHODS: tuple[str, ...]  # Light.shadow
SUBPIXEL_BITS: int  # fixed-point precision of snapped window coordinates (8 => 1/256 px)
TEXTURE_FILTERS: tuple[str, ...]  # a texture's filter, or texture_filter=
TEXTURE_WRAPS: tuple[str, ...]  # a texture's wrap modes
TILE_SIZE_PX: int  # side of the square screen tiles owned by one thread at a time

class RenderOptions(TypedDict, total=False):
    """Renderer.render's options, by name (RENDER_OPTIONS); the required ones first."""
    view: typing.Required[numpy.ndarray]  # world -> view, (4, 4) float64, OpenGL axes
    proj: typing.Required[numpy.ndarray]  # view -> clip, (4, 4) float64
    orthographic: typing.Required[bool]  # an orthographic projection (depth keys are -depth)
    near: typing.Required[float]  # > 0, scene units along the viewing axis
    far: typing.Required[float]  # > near
    outputs: typing.Required[list[str]]  # names from OUTPUTS, at least one
    cull: str  # CULL_MODES (default 'back')
    shading: str  # SHADING_MODELS: 'auto' (default: each material's model, Lambert without one) or one model for every draw
    shading_path: str  # SHADING_PATHS (default 'auto')
    background: tuple[float, float, float]  # colour of uncovered pixels, [0, 1]
    ambient: float  # [0, 1]: the headlight's ambient share, in a scene without lights (default 0.25)
    out: dict[str, numpy.ndarray] | None  # arrays to render into in place
    lights: list[Light]  # the scene's lights, world space (none: the headlight)
    ambient_light: tuple[float, float, float] | None  # the scene's ambient light (None: 0, or the headlight's ambient)
    frequency: str  # FREQUENCIES (default 'pixel')
    srgb: bool  # the colour output sRGB-encoded (default True)
    texture_filter: str | None  # TEXTURE_FILTERS for every texture, or None: each its own
    normal_rotation: tuple[tuple[float, float, float], ...] | None  # rows of the world -> camera rotation for normal_space='camera', or None
    raster: str  # RASTER_ALGORITHMS (default 'edge')
    msaa: int  # 1, 2, 4, 8 or 16 samples per pixel (default 1)
    ssaa: int  # a k x k grid of samples per pixel, k in [1, 8] (default 1)
    primitives: list[Primitive]  # lines and points drawn over the triangles
    line_algorithm: str  # LINE_ALGORITHMS (default 'bresenham')
    lit_kernel: bool  # tests and benchmarks: shade with the lit kernel even where a plain one serves (the same bits; default False)
    cull_double_sided: bool  # cull the draws of double-sided materials too (default False: they are never culled)
    normal_kind: str  # NORMAL_KINDS: the normal output's 'interpolated' vertex normal (default) or the 'shading' normal (normal and bump maps applied)
    alpha_threshold: float | None  # [0, 1]: depth, ids, mask, normal and the surface outputs from the nearest blended fragment whose alpha reaches it, in front of the opaque surface; None (default): the nearest opaque surface's

class Draw:
    """One mesh instance: its mesh, pose, id, colour and material."""
    def __init__(self, *,
                 mesh: MeshData = ...,
                 pose: numpy.ndarray = ...,
                 instance_id: int = ...,
                 color: tuple[float, float, float, float] = ...,
                 material: Material | None = ...,
                 ) -> None: ...
    mesh: MeshData  # the geometry
    pose: numpy.ndarray  # model -> world, (4, 4) float64
    instance_id: int  # the instance_id output's value
    color: tuple[float, float, float, float]  # linear RGBA: the base colour where the mesh has no vertex colours
    material: Material | None  # None: Lambert of the base colour, two-sided

class Light:
    """A light in world space (python/softrast/light.py)."""
    def __init__(self, *,
                 kind: str = ...,
                 radiance: tuple[float, float, float] = ...,
                 position: tuple[float, float, float] = ...,
                 direction: tuple[float, float, float] = ...,
                 inverse_square: bool = ...,
                 cone_scale: float = ...,
                 cone_offset: float = ...,
                 shadow: str = ...,
                 ) -> None: ...
    kind: str  # 'directional', 'point' or 'spot'
    radiance: tuple[float, float, float]  # colour times intensity, linear
    position: tuple[float, float, float]  # point and spot lights
    direction: tuple[float, float, float]  # unit: the direction the light travels
    inverse_square: bool  # point and spot: radiance / r^2
    cone_scale: float  # spot: clamp(cos * cone_scale + cone_offset, 0, 1)^2
    cone_offset: float  # spot: see cone_scale
    shadow: str  # 'none', 'exact' or 'map' (cpp/shadow.hpp)

class Material:
    """A material (python/softrast/material.py states each field's meaning)."""
    def __init__(self, *,
                 model: str = ...,
                 kd_is_base: bool = ...,
                 ka_is_kd: bool = ...,
                 double_sided: bool = ...,
                 ka: tuple[float, float, float] = ...,
                 kd: tuple[float, float, float] = ...,
                 ks: tuple[float, float, float] = ...,
                 shininess: float = ...,
                 metallic: float = ...,
                 roughness: float = ...,
                 emissive: tuple[float, float, float] = ...,
                 base_color_texture: Texture | None = ...,
                 emissive_texture: Texture | None = ...,
                 normal_texture: Texture | None = ...,
                 normal_scale: float = ...,
                 normal_y_down: bool = ...,
                 metallic_roughness_texture: Texture | None = ...,
                 occlusion_texture: Texture | None = ...,
                 occlusion_strength: float = ...,
                 bump_texture: Texture | None = ...,
                 specular_texture: Texture | None = ...,
                 bump_scale: float = ...,
                 alpha_mask: bool = ...,
                 alpha_cutoff: float = ...,
                 alpha_blend: bool = ...,
                 ) -> None: ...
    model: str  # its reflectance model (REFLECTANCE_MODELS), drawn by shading='auto'
    kd_is_base: bool  # kd is the base colour (vertex colours, else the draw's colour)
    ka_is_kd: bool  # ka is kd
    double_sided: bool  # back faces are lit as front faces (else dark side)
    ka: tuple[float, float, float]  # ambient reflectance (unless ka_is_kd)
    kd: tuple[float, float, float]  # diffuse reflectance (unless kd_is_base)
    ks: tuple[float, float, float]  # specular reflectance (phong, blinn_phong)
    shininess: float  # the specular exponent, >= 0
    metallic: float  # pbr: in [0, 1]
    roughness: float  # pbr: in [0, 1]
    emissive: tuple[float, float, float]  # added radiance (times the emissive texture where there is one)
    base_color_texture: Texture | None  # multiplies the base colour (rgb)
    emissive_texture: Texture | None  # emissive times its rgb is added
    normal_texture: Texture | None  # tangent-space normals
    normal_scale: float  # scales the normal texture's x and y
    normal_y_down: bool  # a DirectX-style normal texture (green = -v)
    metallic_roughness_texture: Texture | None  # glTF: green * roughness, blue * metallic
    occlusion_texture: Texture | None  # red: ambient *= 1 + strength (red - 1)
    occlusion_strength: float  # in [0, 1]
    bump_texture: Texture | None  # a height map (its first channel)
    specular_texture: Texture | None  # rgb scales ks (phong, blinn_phong)
    bump_scale: float  # the bump texture's height scale
    alpha_mask: bool  # glTF alphaMode MASK: fragments below alpha_cutoff are discarded
    alpha_cutoff: float  # alpha_mask's threshold
    alpha_blend: bool  # glTF alphaMode BLEND: composited in depth order over what lies behind (not with alpha_mask)

class MeshData:
    # Validates (n,3) float32 positions, (m,3) int32 faces and optional (n,3) float32 normals, (n,4) float32 colors, (n,2) float32 uvs. Views immutable arrays (read-only views of a bytes object) in place and copies any other.
    def __init__(self: MeshData, positions: object, faces: object, normals: object = None, colors: object = None, uvs: object = None) -> None: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_faces(self) -> int: ...

class Primitive:
    """Lines or points (python/softrast/primitives.py), viewed: the record keeps its arrays alive."""
    def __init__(self, *,
                 points: bool = ...,
                 positions: numpy.ndarray = ...,
                 segments: numpy.ndarray | None = ...,
                 colors: numpy.ndarray | None = ...,
                 color: tuple[float, float, float] = ...,
                 width: float = ...,
                 pose: numpy.ndarray = ...,
                 instance_id: int = ...,
                 depth_bias: float = ...,
                 ) -> None: ...
    points: bool  # points (each position) rather than lines (segments)
    positions: numpy.ndarray  # (n, 3) float32, model space
    segments: numpy.ndarray | None  # (m, 2) int32 endpoint indices (lines)
    colors: numpy.ndarray | None  # (n, 3) float32 linear RGB per position
    color: tuple[float, float, float]  # linear RGB without colors
    width: float  # line width or point size, pixels
    pose: numpy.ndarray  # model -> world, (4, 4) float64
    instance_id: int  # the instance_id output's value
    depth_bias: float  # lines: nearer by this fraction of their depth in the depth test (wireframe)

class Renderer:
    # A renderer of width x height pixels on `threads` threads (0: one per core); simd=False runs the generic kernels (the same bits).
    def __init__(self: Renderer, width: int, height: int, threads: int = 0, simd: bool = True) -> None: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def threads(self) -> int: ...
    @property
    def isa(self) -> str: ...
    # Renders the draws (Draw records) with the options (RENDER_OPTIONS, by name): a dict of the requested outputs' arrays (OUTPUT_TABLE gives dtypes and shapes).
    def render(self: Renderer, draws: collections.abc.Sequence[Draw], options: RenderOptions) -> dict: ...

class Texture:
    @typing.overload
    def __init__(self: Texture, image: typing.Annotated[numpy.typing.ArrayLike, numpy.uint8], srgb: bool) -> None: ...
    @typing.overload
    def __init__(self: Texture, image: typing.Annotated[numpy.typing.ArrayLike, numpy.float32]) -> None: ...
    def configure(self: Texture, filter: int, wrap_u: int, wrap_v: int, top_left: bool, max_anisotropy: int) -> None: ...
    def build_mips(self: Texture) -> None: ...
    @property
    def has_mips(self) -> bool: ...
    @property
    def num_levels(self) -> int: ...
    def level_size(self: Texture, arg0: int) -> tuple[int, int]: ...
    def mip(self: Texture, level: int) -> numpy.typing.NDArray[numpy.float32]: ...
    # Samples at n points: (n, 2) uv, (n, 4) derivatives (du/dx, dv/dx, du/dy, dv/dy); (n, 4) linear RGBA, exactly what a render reads.
    def sample(self: Texture, uv: typing.Annotated[numpy.typing.ArrayLike, numpy.float32], duv: typing.Annotated[numpy.typing.ArrayLike, numpy.float32], filter: int) -> numpy.typing.NDArray[numpy.float32]: ...

class _LensRays:
    """One distorted camera's rays at one image size, checked once (distortion.py's _Rays)."""
    def __init__(self: _LensRays, valid: numpy.ndarray, nearest: numpy.ndarray, corner: numpy.ndarray, view_width: int, view_size: int, pixel: numpy.ndarray, xy: numpy.ndarray, slot: numpy.ndarray, cell_start: numpy.ndarray, nx: int, ny: int, frame: typing.Annotated[collections.abc.Sequence[float], "FixedSize(4)"]) -> None: ...

# Gives a light record its shadow maps (python/softrast/shadow_maps.py): faces of (view, proj, orthographic, depth); the depth maps are copied.
def _attach_shadow_map(light: Light, faces: list, bias: float) -> None: ...
# out[p] = the bilinear interpolation of src at pixel p's ray (uint8 rounded half up).
def _distortion_bilinear(rays: _LensRays, weights: numpy.ndarray, src: numpy.ndarray, out: numpy.ndarray) -> None: ...
# Per output pixel, the nearest hit of its own ray among every triangle of the draws (float64): the named outputs, flat.
def _distortion_cast(rays: _LensRays, draws: list, camera_to_world: typing.Annotated[collections.abc.Sequence[float], "FixedSize(9)"], centre: typing.Annotated[collections.abc.Sequence[float], "FixedSize(3)"], near: float, far: float, cull: str, cull_double_sided: bool, outputs: collections.abc.Sequence[str], view: object, threads: int) -> dict: ...
# Testing only: the n-th worker thread started from now on (1 = the next) fails as if the system had refused it; 0 = off.
def _fail_thread_start(n: int) -> None: ...
# Testing only: threads parked for good because they finished a render while the interpreter finalized.
def _parked_threads() -> int: ...
# nvdiffrast's rasterize (softrast.nv) with the core's clipping and raster: triangles given in clip space, image k drawing tri[first:first + count] for ranges[k] = (first, count) with pos[k] (or pos[0] for every image). Writes rast = (u, v, z/w, id + 1) and rast_db = (du/dX, du/dY, dv/dX, dv/dY) (or None) in place, row 0 at the bottom (cpp/clip_raster.hpp), without the GIL; threads: 0 = one per core; simd=False: the generic kernels (the same bits).
def _rasterize_clip(pos: numpy.ndarray, tri: numpy.ndarray, ranges: numpy.ndarray, width: int, height: int, rast: numpy.ndarray, rast_db: object, threads: int = 0, simd: bool = True) -> None: ...
# The sample offsets of an anti-aliasing mode, from each pixel's top-left corner in fixed point (1 / 2**SUBPIXEL_BITS px), in sample order (multisample.hpp).
def _sample_pattern(msaa: int, ssaa: int) -> list[tuple[int, int]]: ...
# PNG file bytes of a uint8 or uint16 (h, w) or (h, w, 1-4) array (any row stride): a filter per row, one deflate block of literals and runs. The GIL is released.
def encode_png(image: numpy.ndarray) -> bytes: ...
# 16-bit grey PNG file bytes of (h, w) int32 ids stored as id + 1 (0 = background, -1); ValueError if an id is outside -1..65534. The GIL is released.
def encode_png_ids(ids: typing.Annotated[numpy.typing.ArrayLike, numpy.int32]) -> bytes: ...
# TIFF file bytes of an (h, w) or (h, w, 1-4) array of 1-, 2- or 4-byte samples, one strip; sample_format 1 unsigned, 2 signed, 3 float; deflated after predictor (1 none, 2 horizontal, 3 floating point) when compress. The GIL is released.
def encode_tiff(image: numpy.ndarray, sample_format: int, compress: bool, predictor: int) -> bytes: ...
# A zlib stream of a contiguous buffer (literals and runs; see encode_png).
def zlib_compress(data: typing_extensions.Buffer) -> bytes: ...
