"""Pictures of robots: off-screen MuJoCo renders, contact sheets, side-by-sides and tree plots.

Rendering uses :class:`mujoco.Renderer` off-screen. MuJoCo picks its OpenGL backend from the
``MUJOCO_GL`` environment variable **when** ``mujoco`` **is first imported**; this module sets
``MUJOCO_GL=egl`` (headless EGL, e.g. Mesa) unless it is already set. To use another backend,
set ``MUJOCO_GL=osmesa`` (software) or ``MUJOCO_GL=glfw`` (a desktop with a display) before
anything imports ``mujoco``. When no GL context can be created, the render functions raise
``RuntimeError("robovae: off-screen rendering unavailable (MUJOCO_GL=...): <reason>")``.

Scenes. A robot file (``.xml``/``.urdf``, loaded with :func:`robovae.data.mjcf.load_robot`, so
Menagerie files whose meshes are missing still load) or a :class:`mujoco.MjSpec` that has no
floor is wrapped with ``MjSpec`` edits: a checkered floor plane under the robot, a spot light
above it (plus a shadowless fill light) and a gradient skybox. A bare :class:`mujoco.MjModel`
cannot be edited that way, so its floor is drawn straight into the render scene instead (no
physics: ``settle_seconds`` needs a floor, from the file or a spec). Bodies without any geom get
a small marker and a "bone" to their parent, so robots with missing meshes still show their
shape, and when most bodies' visible geoms are gone (meshes dropped) the collision geom groups
are shown as well. Models that have a floor are rendered as they are.

Camera. Unless told otherwise the camera is a free camera at azimuth 135°, elevation -20°,
looking at the centre of the robot's bounding box (geom AABBs and body positions after
``mj_forward``, world geoms excluded) from the smallest distance that keeps every box corner in
view (times a margin). ``camera`` dicts may override any of ``lookat``, ``distance``,
``azimuth``, ``elevation``, or name a model camera with ``{"name": "track"}``.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import math  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from robovae.data.graph import children  # noqa: E402
from robovae.data.mjcf import capture_mujoco_warnings, load_robot, robot_root  # noqa: E402
from robovae.errors import RobovaeError  # noqa: E402

Robot = str | os.PathLike | mujoco.MjModel | mujoco.MjSpec
"""Anything :func:`render_robot` accepts: a robot file, a compiled model or a spec."""

DEFAULT_AZIMUTH = 135.0
DEFAULT_ELEVATION = -20.0
NODE_TYPE_NAMES = ("link", "joint", "geom")
NODE_TYPE_COLORS = ("#4C72B0", "#DD8452", "#55A868")
NODE_TYPE_MARKERS = ("o", "s", "^")

_PREFIX = "robovae_"
_PLANE = mujoco.mjtGeom.mjGEOM_PLANE
_HFIELD = mujoco.mjtGeom.mjGEOM_HFIELD
_FLOOR_RGB = ((0.42, 0.47, 0.53), (0.30, 0.35, 0.41))
_TILE_BG = np.array([235, 235, 235], dtype=np.uint8)


# ----------------------------------------------------------------------------------------------
# scene preparation


@dataclass
class _Prepared:
    """A compiled robot ready to render."""

    model: mujoco.MjModel
    data: mujoco.MjData
    name: str
    floor: int = -1  # geom id of the floor we added
    light: int = -1  # light id of the light we added
    inject_floor: bool = False  # bare MjModel without floor: draw one into the scene


def _has_floor(model: mujoco.MjModel) -> bool:
    """True when a world geom is a plane or height field."""
    world = model.geom_bodyid == 0
    return bool(np.any(world & np.isin(model.geom_type, (_PLANE, _HFIELD))))


def _model_name(model: mujoco.MjModel) -> str:
    return bytes(model.names).split(b"\0", 1)[0].decode(errors="replace")


def add_floor(spec: mujoco.MjSpec, light: bool = True, skybox: bool = True) -> mujoco.MjSpec:
    """Add a checkered floor plane at z = 0 (and lights and a skybox) to ``spec`` in place.

    Element names start with ``robovae_``. The floor collides with the robot, so the robot can
    be simulated on it. Returns ``spec``.
    """
    spec.add_texture(name=f"{_PREFIX}grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256, height=256,
                     rgb1=list(_FLOOR_RGB[0]), rgb2=list(_FLOOR_RGB[1]),
                     mark=mujoco.mjtMark.mjMARK_EDGE, markrgb=[0.75, 0.78, 0.82])
    mat = spec.add_material(name=f"{_PREFIX}grid", texrepeat=[1.0, 1.0], texuniform=True,
                            reflectance=0.15)
    textures = list(mat.textures)
    textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = f"{_PREFIX}grid"
    mat.textures = textures
    spec.worldbody.add_geom(name=f"{_PREFIX}floor", type=_PLANE, size=[0.0, 0.0, 0.05],
                            material=f"{_PREFIX}grid", condim=3)
    if skybox:
        spec.add_texture(name=f"{_PREFIX}sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=128, height=768,
                         rgb1=[0.78, 0.86, 0.95], rgb2=[0.98, 0.98, 1.0])
    if light:
        # a spot light casts the shadows (directional-light shadow maps speckle flat faces);
        # a shadowless directional light keeps the far floor lit
        spec.worldbody.add_light(name=f"{_PREFIX}sun", type=mujoco.mjtLightType.mjLIGHT_SPOT,
                                 pos=[0.0, 0.0, 5.0], dir=[0.0, 0.0, -1.0], castshadow=True,
                                 cutoff=45.0, exponent=1.0, attenuation=[1.0, 0.0, 0.0],
                                 diffuse=[0.7, 0.7, 0.7], specular=[0.2, 0.2, 0.2])
        spec.worldbody.add_light(name=f"{_PREFIX}fill",
                                 type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                 dir=[0.0, 0.0, -1.0], castshadow=False,
                                 diffuse=[0.3, 0.3, 0.3], specular=[0.0, 0.0, 0.0])
    return spec


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    with capture_mujoco_warnings():
        return spec.compile()


def _bare_model(model: mujoco.MjModel, width: int, height: int,
                floor: bool) -> _Prepared:
    """A compiled model rendered as is; copied (never changed) when the off-screen buffer must
    grow or, with no floor and no light, the headlight must brighten."""
    inject = floor and not _has_floor(model)
    small = model.vis.global_.offwidth < width or model.vis.global_.offheight < height
    dark = inject and model.nlight == 0
    if small or dark:
        model = mujoco.MjModel.__copy__(model)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        if dark:
            model.vis.headlight.ambient = [0.35, 0.35, 0.35]
            model.vis.headlight.diffuse = [0.65, 0.65, 0.65]
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return _Prepared(model, data, _model_name(model), inject_floor=inject)


def _prepare(robot: Robot, width: int, height: int, floor: bool = True) -> _Prepared:
    """Compile ``robot`` (wrapped in a floor scene when it has none) and run ``mj_forward``."""
    if isinstance(robot, mujoco.MjModel):
        return _bare_model(robot, width, height, floor)
    if isinstance(robot, mujoco.MjSpec):
        spec, name = robot.copy(), robot.modelname
        base = _compile(spec)
    else:
        loaded = load_robot(robot)
        spec, base, name = loaded.spec, loaded.model, Path(robot).stem
    if not floor or _has_floor(base):  # render the model as compiled
        prep = _bare_model(base, width, height, floor=False)
        prep.name = name
        return prep
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, height)
    add_floor(spec, light=True, skybox=not any(t.type == mujoco.mjtTexture.mjTEXTURE_SKYBOX
                                               for t in spec.textures))
    model = _compile(spec)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    prep = _Prepared(model, data, name)
    prep.floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{_PREFIX}floor")
    prep.light = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_LIGHT, f"{_PREFIX}sun")
    _place_floor(prep)
    return prep


def _nice(x: float) -> float:
    """The largest of 1, 2, 5 × 10^k not above ``x``."""
    x = max(x, 1e-4)
    e = 10.0 ** math.floor(math.log10(x))
    return max(m * e for m in (1.0, 2.0, 5.0) if m * e <= x * (1 + 1e-9))


def _place_floor(prep: _Prepared) -> None:
    """Put our floor under the robot (z = min(0, lowest point)), scale its checks, put the
    spot light above the robot (4 robot sizes up), then re-run ``mj_forward``."""
    model, data = prep.model, prep.data
    lo, hi = robot_bounds(model, data)
    size = float(max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-5))
    model.geom_pos[prep.floor] = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]),
                                  min(0.0, float(lo[2]))]
    mat = model.geom_matid[prep.floor]
    if mat >= 0:
        square = _nice(size / 2.0)
        model.mat_texrepeat[mat] = [1.0 / (2.0 * square)] * 2
    if prep.light >= 0:
        model.light_pos[prep.light] = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]),
                                       float(hi[2]) + 4.0 * size]
    # the shadow map and depth range follow the model's extent: keep it robot-sized
    model.stat.extent = max(size, 1e-5)
    model.stat.center = 0.5 * (lo + hi)
    mujoco.mj_forward(model, data)


def _settle(prep: _Prepared, seconds: float) -> None:
    """Simulate ``seconds`` of physics; restore the initial pose if the simulation blows up."""
    model, data = prep.model, prep.data
    if seconds <= 0:
        return
    if prep.inject_floor:
        warnings.warn("robovae: settle_seconds ignored for a bare MjModel without a floor (pass "
                      "the file or an MjSpec to simulate on a floor)", stacklevel=3)
        return
    steps = max(1, int(round(seconds / model.opt.timestep)))
    with capture_mujoco_warnings():
        for _ in range(steps):
            mujoco.mj_step(model, data)
    if not np.isfinite(data.qpos).all():
        warnings.warn("robovae: simulation diverged while settling: rendering the initial pose",
                      stacklevel=3)
        mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)


# ----------------------------------------------------------------------------------------------
# camera


def _robot_points(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """World corners of the robot's geom AABBs and its body positions, ``[P, 3]``."""
    if model.nbody <= 1:
        return np.zeros((1, 3))
    root, _ = robot_root(model)
    bodies = model.body_rootid == root
    sel = bodies[model.geom_bodyid] & ~np.isin(model.geom_type, (_PLANE, _HFIELD))
    pts = [data.xpos[bodies]]
    if sel.any():
        aabb = model.geom_aabb[sel]
        centre, half = aabb[:, :3], aabb[:, 3:]
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                         dtype=float)
        local = centre[:, None, :] + signs[None] * half[:, None, :]  # [G, 8, 3]
        rot = data.geom_xmat[sel].reshape(-1, 3, 3)
        world = np.einsum("gij,gkj->gki", rot, local) + data.geom_xpos[sel][:, None, :]
        pts.append(world.reshape(-1, 3))
    if not pts:
        return np.zeros((1, 3))
    out = np.concatenate(pts)
    out = out[np.isfinite(out).all(axis=1)]
    return out if len(out) else np.zeros((1, 3))


def robot_bounds(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned ``(lo, hi)`` corners of the robot in world frame, from the geom AABBs
    (planes and height fields excluded) and body positions of ``data``.

    The robot is the top-level body with the largest subtree, as in the robot graph
    (:func:`robovae.data.mjcf.robot_root`): props such as balls and targets are left out.
    """
    pts = _robot_points(model, data)
    return pts.min(axis=0), pts.max(axis=0)


def _camera_axes(azimuth: float, elevation: float) -> tuple[np.ndarray, ...]:
    """MuJoCo's free-camera (forward, up, right) unit vectors."""
    az, el = math.radians(azimuth), math.radians(elevation)
    forward = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    up = np.array([-math.sin(el) * math.cos(az), -math.sin(el) * math.sin(az), math.cos(el)])
    return forward, up, np.cross(forward, up)


def auto_camera(model: mujoco.MjModel, data: mujoco.MjData | None = None, *,
                azimuth: float = DEFAULT_AZIMUTH, elevation: float = DEFAULT_ELEVATION,
                aspect: float = 4 / 3, margin: float = 1.15) -> dict[str, Any]:
    """A free camera framing the robot: looks at its bounding-box centre from ``azimuth`` /
    ``elevation`` (degrees), as close as keeps every bounding point in the view (× ``margin``).

    Args:
        model: the compiled robot.
        data: its state; defaults to the ``mj_forward`` of ``qpos0``.
        aspect: image width / height (the horizontal field of view follows from it).

    Returns:
        ``{"lookat": [x, y, z], "distance": d, "azimuth": a, "elevation": e}``.
    """
    if data is None:
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
    pts = _robot_points(model, data)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = 0.5 * (lo + hi)
    forward, up, right = _camera_axes(azimuth, elevation)
    rel = pts - centre
    x, y, z = rel @ right, rel @ up, rel @ forward
    tan_y = math.tan(math.radians(model.vis.global_.fovy) / 2.0)
    tan_x = tan_y * aspect
    need = np.maximum(np.abs(x) / tan_x, np.abs(y) / tan_y) - z
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    distance = max(float(need.max()) * margin, radius * 1.05, 1e-4)
    return {"lookat": centre.tolist(), "distance": distance, "azimuth": float(azimuth),
            "elevation": float(elevation)}


def _resolve_camera(prep: _Prepared, camera: dict | None, aspect: float) -> dict[str, Any]:
    camera = dict(camera or {})
    if "name" in camera:
        return camera
    auto = auto_camera(prep.model, prep.data,
                       azimuth=camera.get("azimuth", DEFAULT_AZIMUTH),
                       elevation=camera.get("elevation", DEFAULT_ELEVATION), aspect=aspect)
    auto.update(camera)
    return auto


def _mjv_camera(model: mujoco.MjModel, camera: dict[str, Any]) -> mujoco.MjvCamera | int:
    if "name" in camera:
        cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera["name"])
        if cid < 0:
            raise ValueError(f"robovae: no camera named {camera['name']!r} in the model")
        return cid
    unknown = set(camera) - {"lookat", "distance", "azimuth", "elevation"}
    if unknown:
        raise ValueError(f"robovae: unknown camera keys {sorted(unknown)}")
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = camera["lookat"]
    cam.distance = float(camera["distance"])
    cam.azimuth = float(camera["azimuth"])
    cam.elevation = float(camera["elevation"])
    return cam


# ----------------------------------------------------------------------------------------------
# rendering


def _scene_option(model: mujoco.MjModel) -> mujoco.MjvOption:
    """Default visual options, plus every geom group when most bodies' visible geoms are gone
    (e.g. Menagerie visual meshes dropped, only group-3 collision geoms left) and no skin
    covers them, minus rangefinder rays."""
    opt = mujoco.MjvOption()
    robot = (model.geom_bodyid > 0) & (model.geom_rgba[:, 3] > 0)
    shown = robot & (model.geom_group < 3) & (model.geom_group >= 0)
    bodies_any = set(model.geom_bodyid[robot].tolist())
    bodies_shown = set(model.geom_bodyid[shown].tolist())
    if model.nskin == 0 and bodies_any and len(bodies_shown) < 0.5 * len(bodies_any):
        opt.geomgroup[:] = 1
    opt.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = 0
    return opt


def _add_geom(scene: mujoco.MjvScene, gtype: int, size: Sequence[float], pos: Sequence[float],
              rgba: Sequence[float], mat: np.ndarray | None = None) -> mujoco.MjvGeom | None:
    if scene.ngeom >= scene.maxgeom:
        return None
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, int(gtype), np.asarray(size, dtype=np.float64),
                        np.asarray(pos, dtype=np.float64),
                        (np.eye(3) if mat is None else mat).reshape(9).astype(np.float64),
                        np.asarray(rgba, dtype=np.float32))
    geom.category = mujoco.mjtCatBit.mjCAT_DECOR
    scene.ngeom += 1
    return geom


def _inject_floor(prep: _Prepared, scene: mujoco.MjvScene) -> None:
    """A checkered floor of thin boxes under the robot (bare MjModel without floor)."""
    lo, hi = robot_bounds(prep.model, prep.data)
    size = float(max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-5))
    square = _nice(size / 2.0)
    n = 12
    cx = math.floor(0.5 * (lo[0] + hi[0]) / square) * square
    cy = math.floor(0.5 * (lo[1] + hi[1]) / square) * square
    z = min(0.0, float(lo[2])) - 0.01 * square
    for i in range(-n, n):
        for j in range(-n, n):
            rgb = _FLOOR_RGB[(i + j) % 2]
            _add_geom(scene, mujoco.mjtGeom.mjGEOM_BOX, [square / 2, square / 2, 0.01 * square],
                      [cx + (i + 0.5) * square, cy + (j + 0.5) * square, z], [*rgb, 1.0])


def _inject_skeleton(prep: _Prepared, scene: mujoco.MjvScene) -> None:
    """A marker at every geom-less body and a bone to its parent body."""
    model, data = prep.model, prep.data
    if model.nbody <= 1:
        return
    has_geom = np.bincount(model.geom_bodyid, minlength=model.nbody) > 0
    bare = [b for b in range(1, model.nbody) if not has_geom[b]]
    if not bare:
        return
    lo, hi = robot_bounds(model, data)
    width = max(0.01 * float(np.linalg.norm(hi - lo)), 1e-6)
    rgba = [0.85, 0.55, 0.2, 1.0]
    for b in bare:
        _add_geom(scene, mujoco.mjtGeom.mjGEOM_SPHERE, [1.6 * width] * 3, data.xpos[b], rgba)
        p = model.body_parentid[b]
        if p > 0 and np.linalg.norm(data.xpos[b] - data.xpos[p]) > 1e-6:
            geom = _add_geom(scene, mujoco.mjtGeom.mjGEOM_CAPSULE, [width] * 3, data.xpos[b], rgba)
            if geom is not None:
                mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, width,
                                     np.asarray(data.xpos[p], dtype=np.float64),
                                     np.asarray(data.xpos[b], dtype=np.float64))


def _gl_backend() -> str:
    try:
        from mujoco.rendering.classic import gl_context
        return str(getattr(gl_context, "_MUJOCO_GL", os.environ.get("MUJOCO_GL", "")))
    except ImportError:
        return os.environ.get("MUJOCO_GL", "")


_BACKEND_CHECKED = False


def _match_backend() -> None:
    """Honour ``MUJOCO_GL=egl|osmesa`` even when ``mujoco`` was imported before it was set.

    MuJoCo reads ``MUJOCO_GL`` once, at import. When something imported ``mujoco`` before this
    module set the variable, MuJoCo chose its default (GLFW, which needs a display); if the
    variable now asks for a headless backend, switch MuJoCo's context class to it once.
    """
    global _BACKEND_CHECKED
    if _BACKEND_CHECKED:
        return
    _BACKEND_CHECKED = True
    wanted = os.environ.get("MUJOCO_GL", "").lower().strip()
    try:
        from mujoco.rendering.classic import gl_context
    except ImportError:  # pragma: no cover - other mujoco layouts: leave them alone
        return
    if getattr(gl_context, "_MUJOCO_GL", wanted) != "" or wanted not in ("egl", "osmesa"):
        return
    try:
        if wanted == "egl":
            from mujoco.egl import GLContext
        else:
            from mujoco.osmesa import GLContext
    except Exception:  # noqa: BLE001 - keep MuJoCo's choice; creation will report the error
        return
    gl_context.GLContext = GLContext
    gl_context._MUJOCO_GL = wanted


def _make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    _match_backend()
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as e:  # GL context creation fails in many ways (ImportError, EGL errors)
        raise RuntimeError(f"robovae: off-screen rendering unavailable (MUJOCO_GL="
                           f"{_gl_backend() or '<unset>'}): {type(e).__name__}: {e}") from e


def _render_prepared(prep: _Prepared, width: int, height: int,
                     camera: dict[str, Any], skeleton: bool = True) -> np.ndarray:
    renderer = _make_renderer(prep.model, width, height)
    try:
        renderer.update_scene(prep.data, camera=_mjv_camera(prep.model, camera),
                              scene_option=_scene_option(prep.model))
        if prep.inject_floor:
            _inject_floor(prep, renderer.scene)
        if skeleton:
            _inject_skeleton(prep, renderer.scene)
        return np.ascontiguousarray(renderer.render(), dtype=np.uint8)
    finally:
        renderer.close()


def render_robot(model_or_path: Robot, width: int = 480, height: int = 360,
                 camera: dict | None = None, settle_seconds: float = 0.0, *,
                 floor: bool = True, skeleton: bool = True) -> np.ndarray:
    """Render a robot off-screen.

    Args:
        model_or_path: a robot file (``.xml``/``.urdf``; missing meshes are dropped), a
            compiled ``mujoco.MjModel`` or a ``mujoco.MjSpec`` (copied, not changed).
        width: image width in pixels.
        height: image height in pixels.
        camera: overrides of the automatic camera (keys ``lookat``, ``distance``, ``azimuth``,
            ``elevation``; the distance is re-fitted when only the angles are given), or
            ``{"name": <model camera>}``.
        settle_seconds: simulate this long (on the floor) before rendering.
        floor: add a floor scene when the model has none.
        skeleton: draw markers and bones for bodies without geoms.

    Returns:
        ``uint8`` array ``[height, width, 3]``.

    Raises:
        RobotFileError: the file cannot be loaded.
        RuntimeError: no off-screen OpenGL context (see the module docstring).
    """
    prep = _prepare(model_or_path, width, height, floor=floor)
    _settle(prep, settle_seconds)
    cam = _resolve_camera(prep, camera, width / height)
    return _render_prepared(prep, width, height, cam, skeleton=skeleton)


def robot_camera(model_or_path: Robot, width: int = 480, height: int = 360,
                 settle_seconds: float = 0.0) -> dict[str, Any]:
    """The automatic camera :func:`render_robot` would use (e.g. to render others alike)."""
    prep = _prepare(model_or_path, width, height)
    _settle(prep, settle_seconds)
    return _resolve_camera(prep, None, width / height)


# ----------------------------------------------------------------------------------------------
# images and figures


def save_png(image: np.ndarray, path: str | os.PathLike) -> Path:
    """Write an ``[H, W, 3|4]`` ``uint8`` (or ``[0, 1]`` float) image as PNG; returns the path.

    Uses Pillow when installed (a matplotlib dependency), else ``matplotlib.pyplot.imsave``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = (np.clip(img, 0.0, 1.0) * 255).round().astype(np.uint8)
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover - Pillow comes with matplotlib
        import matplotlib.image

        matplotlib.image.imsave(path, img)
    else:
        Image.fromarray(img).save(path, format="PNG")
    return path


def _label_of(item: Robot, index: int) -> str:
    if isinstance(item, mujoco.MjModel):
        return _model_name(item) or f"robot {index}"
    if isinstance(item, mujoco.MjSpec):
        return item.modelname or f"robot {index}"
    return Path(item).stem


def _save_labelled(image: np.ndarray, path: str | os.PathLike,
                   labels: Sequence[tuple[float, float, str]], fontsize: float = 10.0,
                   dpi: int = 100) -> Path:
    """Save ``image`` at its exact pixel size with text boxes at pixel positions (x, y from the
    top-left corner)."""
    h, w = image.shape[:2]
    fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi)
    fig.figimage(image, xo=0, yo=0, origin="upper")
    for x, y, text in labels:
        if text:
            fig.text(x / w, 1.0 - y / h, text, ha="left", va="top", fontsize=fontsize,
                     family="sans-serif",
                     bbox={"boxstyle": "round,pad=0.25", "facecolor": "white", "alpha": 0.75,
                           "edgecolor": "none"})
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, format="png")
    return path


def contact_sheet(items: Sequence[Robot], path: str | os.PathLike, columns: int = 5,
                  size: tuple[int, int] = (240, 180), labels: Sequence[str] | None = None,
                  max_items: int | None = None, settle_seconds: float = 0.0) -> Path:
    """A grid PNG of robot renders with labels.

    Args:
        items: robot files, models or specs (the first ``max_items`` are drawn).
        path: output PNG; its size is ``(columns·w) × (rows·h)`` pixels for ``size = (w, h)``
            (fewer columns when there are fewer items).
        labels: one label per item; default: file stem / model name.
        settle_seconds: passed to :func:`render_robot`.

    A robot that cannot be loaded gets a grey tile labelled with the error (and a warning).

    Returns:
        ``path`` as a ``Path``.
    """
    items = list(items)[: max_items if max_items is not None else None]
    if not items:
        raise ValueError("robovae: contact_sheet needs at least one robot")
    labels = list(labels) if labels is not None else [_label_of(it, i)
                                                      for i, it in enumerate(items)]
    if len(labels) < len(items):
        raise ValueError(f"robovae: {len(labels)} labels for {len(items)} robots")
    w, h = size
    cols = max(1, min(columns, len(items)))
    rows = math.ceil(len(items) / cols)
    sheet = np.empty((rows * h, cols * w, 3), dtype=np.uint8)
    sheet[:] = _TILE_BG
    texts = []
    for k, item in enumerate(items):
        r, c = divmod(k, cols)
        label = labels[k]
        try:
            tile = render_robot(item, w, h, settle_seconds=settle_seconds)
        except (RobovaeError, ValueError) as e:
            warnings.warn(f"robovae: contact sheet tile {k} failed: {e}", stacklevel=2)
            tile = np.full((h, w, 3), 160, dtype=np.uint8)
            label = f"{label}\n(failed)"
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = tile
        texts.append((c * w + 4, r * h + 4, label))
    sheet[:, ::w] = 255  # thin separators between tiles
    sheet[::h, :] = 255
    return _save_labelled(sheet, path, texts, fontsize=max(6.0, min(10.0, h / 20)))


def side_by_side(original: Robot, reconstruction: Robot, path: str | os.PathLike,
                 titles: tuple[str, str] = ("original", "reconstruction"),
                 size: tuple[int, int] = (480, 360), settle_seconds: float = 0.0) -> Path:
    """Render two robots from the same camera (fitted to ``original``) next to each other,
    like the paper's Figure 4. Writes a ``(2w) × h`` PNG and returns its path."""
    w, h = size
    prep = _prepare(original, w, h)
    _settle(prep, settle_seconds)
    cam = _resolve_camera(prep, None, w / h)
    left = _render_prepared(prep, w, h, cam)
    right = render_robot(reconstruction, w, h, camera=cam, settle_seconds=settle_seconds)
    image = np.concatenate([left, right], axis=1)
    image[:, w - 1:w + 1] = 255
    return _save_labelled(image, path, [(6, 6, titles[0]), (w + 6, 6, titles[1])],
                          fontsize=max(8.0, min(14.0, h / 24)))


# ----------------------------------------------------------------------------------------------
# robot tree plots


def tree_layout(parent: Sequence[int] | Any) -> dict[int, tuple[float, float]]:
    """A tidy top-down layout of a pre-order tree: leaves on consecutive x in pre-order, each
    parent centred over its first and last child, ``y = -depth``. Returns ``{node: (x, y)}``."""
    par = parent.tolist() if hasattr(parent, "tolist") else list(parent)
    n = len(par)
    kids = children(par)
    depth = [0] * n
    for i in range(1, n):
        depth[i] = depth[par[i]] + 1
    x = [0.0] * n
    leaf = 0
    for i in range(n):  # pre-order: leaves left to right
        if not kids[i]:
            x[i] = float(leaf)
            leaf += 1
    for i in reversed(range(n)):  # children have larger indices than their parent
        if kids[i]:
            x[i] = 0.5 * (x[kids[i][0]] + x[kids[i][-1]])
    return {i: (x[i], -float(depth[i])) for i in range(n)}


def draw_graph(data: Any, path: str | os.PathLike | None = None, ax: Any = None,
               title: str | None = None,
               type_names: Sequence[str] = NODE_TYPE_NAMES) -> Figure | Path:
    """Draw a robot tree (root at the top), nodes coloured and shaped by type, with a legend.

    Args:
        data: a :class:`~robovae.data.graph.RobotData` (or anything with ``parent`` and
            optionally ``node_type``).
        path: write a PNG there and return the path; otherwise return the figure.
        ax: draw into this matplotlib axes instead of a new figure.
        title: axes title; default: ``data.name``.
        type_names: legend names of node types 0, 1, 2.
    """
    import networkx as nx

    parent = data.parent.tolist() if hasattr(data.parent, "tolist") else list(data.parent)
    n = len(parent)
    types_attr = getattr(data, "node_type", None)
    types = ([int(t) for t in types_attr.tolist()] if types_attr is not None else [0] * n)
    pos = tree_layout(parent)
    g = nx.DiGraph()
    g.add_nodes_from(range(n))
    g.add_edges_from((p, i) for i, p in enumerate(parent) if p >= 0)
    leaves = max(1, sum(1 for k in children(parent) if not k))
    depth = int(-min(y for _, y in pos.values())) if n else 0
    if ax is None:
        fig = Figure(figsize=(min(max(4.0, 0.42 * leaves + 1.5), 40.0),
                              min(max(3.0, 0.75 * (depth + 1) + 1.0), 30.0)), dpi=100)
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    node_size = 260 if n <= 40 else 120 if n <= 150 else 40
    nx.draw_networkx_edges(g, pos, ax=ax, arrows=False, edge_color="#888888", width=1.2)
    handles = []
    for t in sorted(set(types)):
        nodes = [i for i in range(n) if types[i] == t]
        name = type_names[t] if t < len(type_names) else f"type {t}"
        color = NODE_TYPE_COLORS[t % len(NODE_TYPE_COLORS)]
        marker = NODE_TYPE_MARKERS[t % len(NODE_TYPE_MARKERS)]
        nx.draw_networkx_nodes(g, pos, nodelist=nodes, ax=ax, node_color=color,
                               node_shape=marker, node_size=node_size, edgecolors="black",
                               linewidths=0.6)
        handles.append(Line2D([], [], linestyle="", marker=marker, markerfacecolor=color,
                              markeredgecolor="black", markersize=9,
                              label=f"{name} ({len(nodes)})"))
    if n <= 60:
        nx.draw_networkx_labels(g, pos, ax=ax, font_size=7, font_color="white")
    ax.legend(handles=handles, loc="upper right", fontsize=8, frameon=True)
    ax.set_title(title if title is not None else (getattr(data, "name", "") or "robot graph"))
    ax.set_axis_off()
    ax.margins(0.08)
    if path is None:
        return fig
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches="tight", format="png")
    return path
