"""The scene a robot is rendered in: a floor, lights, a sky, markers for bodies without geoms.

A robot file (``.xml``/``.urdf``, loaded with :func:`robovae.data.loading.load_robot`, so Menagerie
files whose meshes are missing still load) or a :class:`mujoco.MjSpec` that has no floor is
wrapped with ``MjSpec`` edits (:func:`add_floor`): a checkered floor plane at ``z = min(0,
lowest robot point)`` whose squares are the largest ``1, 2 or 5 × 10^k`` m not above half the
robot's size, a spot light 4 robot sizes above the robot (plus a shadowless fill light) and a
gradient skybox. A bare :class:`mujoco.MjModel` cannot be edited that way, so its floor is drawn
straight into the render scene instead (:func:`inject_floor`; no physics: :func:`settle` needs a
floor, from the file or a spec), from a copy when its buffer or lighting must change. Bodies
without any geom get a small marker and a "bone" to their parent (:func:`inject_skeleton`), and
when most bodies' visible geoms are gone (meshes dropped) the collision geom groups are shown as
well (:func:`scene_option`). Models that have a floor are rendered as they are. A robot is shown
in its rest pose: its keyframe named in :data:`~robovae.evaluate.quality.stage.REST_KEYFRAMES`
(``home``: a generated robot's balanced stance, :mod:`robovae.generate.bipeds`) when it has one,
else ``qpos0``, joints clipped into their ranges
(:func:`~robovae.evaluate.quality.stage.rest_pose`: where the quality measures start it).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeAlias

import mujoco
import numpy as np

from robovae.data.loading import capture_mujoco_warnings, load_robot
from robovae.evaluate.camera import robot_bounds
from robovae.evaluate.quality.stage import rest_key, rest_pose

__all__ = ["Prepared", "Robot", "add_floor", "has_floor", "inject_floor", "inject_skeleton",
           "model_name", "prepare", "scene_option", "settle"]

Robot: TypeAlias = str | os.PathLike | mujoco.MjModel | mujoco.MjSpec
"""Anything the renderer accepts: a robot file, a compiled model or a spec."""

_PREFIX = "robovae_"
_PLANE = mujoco.mjtGeom.mjGEOM_PLANE
_HFIELD = mujoco.mjtGeom.mjGEOM_HFIELD
_FLOOR_RGB = ((0.42, 0.47, 0.53), (0.30, 0.35, 0.41))


@dataclass
class Prepared:
    """A compiled robot ready to render.

    Attributes:
        model: the compiled model (with the added floor and lights, if any).
        data: its state after ``mj_forward``.
        name: the robot's name (file stem or model name).
        floor: geom id of the floor added here (-1: none).
        light: light id of the spot light added here (-1: none).
        inject_floor: a bare ``MjModel`` without floor: :func:`inject_floor` draws one.
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    name: str
    floor: int = -1
    light: int = -1
    inject_floor: bool = False


def has_floor(model: mujoco.MjModel) -> bool:
    """True when a world geom is a plane or height field."""
    world = model.geom_bodyid == 0
    return bool(np.any(world & np.isin(model.geom_type, (_PLANE, _HFIELD))))


def model_name(model: mujoco.MjModel) -> str:
    """The model's name (``<mujoco model="...">``)."""
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
                floor: bool) -> Prepared:
    """A compiled model rendered as is; copied (never changed) when the off-screen buffer must
    grow or, with no floor and no light, the headlight must brighten."""
    inject = floor and not has_floor(model)
    small = model.vis.global_.offwidth < width or model.vis.global_.offheight < height
    dark = inject and model.nlight == 0
    if small or dark:
        model = mujoco.MjModel.__copy__(model)
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, height)
        if dark:
            model.vis.headlight.ambient = [0.35, 0.35, 0.35]
            model.vis.headlight.diffuse = [0.65, 0.65, 0.65]
    data = _at_rest(model)
    return Prepared(model, data, model_name(model), inject_floor=inject)


def prepare(robot: Robot, width: int, height: int, floor: bool = True) -> Prepared:
    """Compile ``robot`` (wrapped in a floor scene when ``floor`` and it has none; module
    docstring), with an off-screen buffer of at least ``width × height``, and run
    ``mj_forward``.

    Raises:
        RobotFileError: the file cannot be loaded.
        ValueError: MuJoCo rejects the spec.
    """
    if isinstance(robot, mujoco.MjModel):
        return _bare_model(robot, width, height, floor)
    if isinstance(robot, mujoco.MjSpec):
        spec, name = robot.copy(), robot.modelname
        base = _compile(spec)
    else:
        loaded = load_robot(robot)
        spec, base, name = loaded.spec, loaded.model, Path(robot).stem
    if not floor or has_floor(base):  # render the model as compiled
        prep = _bare_model(base, width, height, floor=False)
        prep.name = name
        return prep
    spec.visual.global_.offwidth = max(spec.visual.global_.offwidth, width)
    spec.visual.global_.offheight = max(spec.visual.global_.offheight, height)
    add_floor(spec, light=True, skybox=not any(t.type == mujoco.mjtTexture.mjTEXTURE_SKYBOX
                                               for t in spec.textures))
    model = _compile(spec)
    data = _at_rest(model)
    prep = Prepared(model, data, name)
    prep.floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"{_PREFIX}floor")
    prep.light = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_LIGHT, f"{_PREFIX}sun")
    _place_floor(prep)
    return prep


def _at_rest(model: mujoco.MjModel) -> mujoco.MjData:
    """Data at the robot's rest pose, where the quality measures start it
    (:func:`~robovae.evaluate.quality.stage.rest_pose`: its rest keyframe, else ``qpos0``,
    joints clipped into their ranges), after ``mj_forward``."""
    data = mujoco.MjData(model)
    key = rest_key(model)
    if key >= 0:
        mujoco.mj_resetDataKeyframe(model, data, key)  # its mocap poses and controls too
    data.qpos[:] = rest_pose(model)
    mujoco.mj_forward(model, data)
    return data


def _nice(x: float) -> float:
    """The largest of 1, 2, 5 × 10^k not above ``x``."""
    x = max(x, 1e-4)
    e = 10.0 ** math.floor(math.log10(x))
    return max(m * e for m in (1.0, 2.0, 5.0) if m * e <= x * (1 + 1e-9))


def _place_floor(prep: Prepared) -> None:
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


def settle(prep: Prepared, seconds: float) -> None:
    """Simulate ``seconds`` of physics with zero controls; restore the initial pose (with a
    warning) if the state becomes non-finite. A bare model without floor is not simulated
    (warning)."""
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


def scene_option(model: mujoco.MjModel) -> mujoco.MjvOption:
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


def inject_floor(prep: Prepared, scene: mujoco.MjvScene) -> None:
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


def inject_skeleton(prep: Prepared, scene: mujoco.MjvScene) -> None:
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
