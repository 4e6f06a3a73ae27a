"""A Scene as the core's records: draws (meshes, lines, points, wireframes), lights with their
shadow maps, and the textures a render needs."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from . import _core
from .primitives import Lines
from .scene import Scene
from .shadow_maps import map_cameras, occluder_bounds
from .texture import FILTERS_WITH_MIPS


def _caster_scene(scene: Scene) -> Scene:
    """The scene's mesh instances that cast shadows (not blended), without lights, lines or
    points: what a shadow map sees."""
    casters = Scene()
    for inst in scene.instances:
        if inst.material is None or inst.material.alpha_mode != "blend":
            casters.add(inst.mesh, pose=inst.pose, instance_id=inst.instance_id, color=inst.color,
                        material=inst.material)
    return casters


def _light_maps(scene: Scene, li: Any, pose: np.ndarray, make_renderer: Callable[[int], Any]) -> list[Any]:
    """A shadow-mapped light's faces (view, proj, orthographic, depth), rendered from the cameras
    shadow_maps.map_cameras fits to the occluders by ``make_renderer(n)``, an n x n Renderer."""
    light = li.light
    corners = occluder_bounds(scene.instances)
    if corners is None:
        return []
    n = light.shadow_resolution
    fields = light._record_fields(pose)
    cams = map_cameras(light._kind, np.asarray(fields["position"]),
                       np.asarray(fields["direction"]), getattr(light, "outer_cone", 0.0),
                       corners, n)
    casters = scene._cached("shadow_casters", lambda: _caster_scene(scene))
    r = make_renderer(n)
    faces = []
    for cam in cams:
        depth = r.render(casters, cam, outputs=("depth",), cull="none").depth
        view, proj = cam._render_matrices(n, n)
        faces.append((view, proj, cam.orthographic, np.ascontiguousarray(depth)))
    return faces


def _lights(scene: Scene, view: Any, shadows: str | bool | None,
            make_renderer: Callable[[int], Any]) -> list[Any]:
    """The core's light records (world space) of the scene's lights for one render, cached in the
    scene for the last view matrix (cameras keep one array per pose) and shadow override:
    camera-space lights move with it. A scene without lights gets the headlight from the core."""
    cached = scene._render_cache.get("lights")
    version = scene.__dict__.get("_version", 0)
    if cached is not None and cached[0] == version and cached[1] is view and cached[3] == shadows:
        return cached[2]
    records = []
    cam_to_world = None
    for li in list(scene._lights):
        pose = li.pose
        if li.camera_space:
            if cam_to_world is None:
                cam_to_world = np.linalg.inv(np.asarray(view, dtype=np.float64))
            pose = cam_to_world @ pose
        method = li.light.shadows if shadows is None else shadows
        if method != "map":
            records.append(li.light._core(pose, shadows))
            continue
        # A shadow-mapped light's record holds its maps: kept in the scene until it changes
        # (not for a camera-space light, whose pose follows every view).
        def make(li=li, pose=pose) -> Any:
            return li.light._core(pose, shadows, _light_maps(scene, li, pose, make_renderer))
        records.append(make() if li.camera_space else
                       scene._cached(("shadow_map", li.light, pose.tobytes(), shadows), make))
    # Stored with the version read before the lights were: used only while it is current.
    scene._render_cache["lights"] = (version, view, records, shadows)
    return records


def _primitive_draws(scene: Scene) -> list[Any]:
    """The core's records of the scene's lines and points (cached in the scene until it
    changes); each holds its object's read-only arrays, which the core views during a render."""
    return scene._cached("primitives", lambda: [
        p.item._core_record(p.pose, p.instance_id) for p in scene.primitives])


# render(wireframe=True): in the depth test an edge counts as nearer by this fraction of its depth,
# so it wins over its own faces (whose depth at a pixel centre differs from the edge's nearest
# point by up to half a pixel's depth slope) and loses to surfaces in front by more than that.
WIREFRAME_DEPTH_BIAS = 2.0**-8


def _wireframe_draws(scene: Scene, line_color: tuple, line_width: float) -> list[Any]:
    """Line records of every mesh instance's unique edges (cached in the scene until it changes;
    one Lines per mesh, shared by its instances)."""
    def build() -> list[Any]:
        per_mesh: dict[int, Lines] = {}
        records = []
        for inst in scene.instances:
            mesh = inst.mesh
            lines = per_mesh.get(id(mesh))
            if lines is None:
                faces = np.asarray(mesh.faces)
                edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
                edges = np.unique(edges, axis=0) if len(edges) else edges.reshape(0, 2)
                lines = per_mesh[id(mesh)] = Lines(mesh.positions, edges, width=line_width,
                                                   color=line_color)
            records.append(lines._core_record(inst.pose, inst.instance_id,
                                              depth_bias=WIREFRAME_DEPTH_BIAS))
        return records

    return scene._cached(("wireframe", line_color, line_width), build)


def _draws(scene: Scene) -> list[Any]:
    """The core's draw records (``softrast._core.Draw``), cached in the scene until it changes.
    The core decides how each is shaded (its material's model, or the render's shading=).
    A scene edited by another thread meanwhile: see Scene._cached."""
    return scene._cached("draws", lambda: [
        _core.Draw(mesh=i.mesh._core_data(), pose=i.pose, instance_id=i.instance_id,
                   color=i.color, material=i.material._core if i.material is not None else None)
        for i in scene.instances])


def _textures(scene: Scene) -> list[tuple[Any, Any]]:
    """(Texture, its core texture) of every texture slot of the scene's materials, as the draws
    use them (cached in the scene until it changes)."""
    cached = scene._render_cache.get("textures")
    if cached is None:
        cached, seen = [], set()
        for inst in scene._instances:
            mat = inst.material
            if mat is None:
                continue
            for slot in mat._TEXTURE_SLOTS:
                tex = getattr(mat, slot)
                if tex is not None:
                    core = tex._core(slot in ("base_color_texture", "emissive_texture"))  # as Material
                    if id(core) not in seen:
                        seen.add(id(core))
                        cached.append((tex, core))
        scene._render_cache["textures"] = cached
    return cached


def _check_mip_budgets(scene: Scene, texture_filter: str | None) -> None:
    """The mip chains this render builds (the core builds those its filters need, once per
    texture: cpp/bind/render.cpp), each checked against the memory budget first."""
    for tex, core in _textures(scene):
        if (texture_filter or tex.filter) in FILTERS_WITH_MIPS and not core.has_mips:
            tex._check_mips(core)
