"""softrast: a fast, exact, deterministic CPU software rasterizer.

Conventions (see README): world and view space are right-handed; cameras look down -z (OpenGL)
unless an IntrinsicsCamera uses convention="opencv"; image row 0 is the top; depth is the
distance along the camera's viewing axis in scene units, 0 where nothing was hit.
"""
from ._version import __version__
from ._core import MAX_IMAGE_SIDE, MAX_THREADS, OUTPUT_TABLE, OUTPUTS, SUBPIXEL_BITS, TILE_SIZE_PX
from .camera import Camera, IntrinsicsCamera, OrthographicCamera, PerspectiveCamera
from .dataset import DatasetJob, load_cameras, render_dataset, write_dataset
from .displace import displace
from .interop import from_pyrender, to_pyrender
from .io import imread, imwrite
from .light import DirectionalLight, Light, PointLight, SpotLight
from .limits import get_memory_budget, set_memory_budget
from .files.load import load_mesh, load_scene
from .material import Material
from .mesh import Mesh, PrecisionWarning
from .primitives import Lines, Points
from .poses import look_at_pose, orbit, sphere_poses
from .options import RenderOptions
from .render import Frame, Renderer, sample_positions
from .scene import Scene
from .texture import Texture, load_texture
from . import opencv  # noqa: E402 (helpers; cv2 is imported only when draw_outline runs)
from . import nv  # noqa: E402


__all__ = [
    "Camera",
    "DatasetJob",
    "DirectionalLight",
    "Frame",
    "IntrinsicsCamera",
    "Light",
    "Lines",
    "MAX_IMAGE_SIDE",
    "MAX_THREADS",
    "Material",
    "Mesh",
    "OUTPUTS",
    "OUTPUT_TABLE",
    "OrthographicCamera",
    "PerspectiveCamera",
    "PointLight",
    "Points",
    "PrecisionWarning",
    "RenderOptions",
    "Renderer",
    "SUBPIXEL_BITS",
    "Scene",
    "SpotLight",
    "Texture",
    "TILE_SIZE_PX",
    "displace",
    "from_pyrender",
    "get_memory_budget",
    "imread",
    "imwrite",
    "load_cameras",
    "load_mesh",
    "load_scene",
    "load_texture",
    "look_at_pose",
    "orbit",
    "render_dataset",
    "set_memory_budget",
    "sample_positions",
    "sphere_poses",
    "to_pyrender",
    "write_dataset",
]
