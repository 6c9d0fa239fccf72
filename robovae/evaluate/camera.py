"""Camera framing: a free camera that shows the whole robot.

The robot is the top-level body with the largest subtree (:func:`robovae.data.loading.robot_root`);
props such as balls and targets are left out. Its extent is the set of corners of its geoms'
bounding boxes (planes and height fields excluded) and its body positions, in the world frame of
``data`` (:func:`robot_points`, :func:`robot_bounds`).

:func:`auto_camera` looks at the centre of that box from azimuth/elevation ``(a, e)`` (degrees;
default :data:`DEFAULT_AZIMUTH`, :data:`DEFAULT_ELEVATION`) and backs off to the smallest
distance ``d`` at which every point ``p`` is in view: with ``r = p - centre`` in camera axes
``(x, y, z)`` (right, up, forward; :func:`camera_axes`) and ``tan_y = tan(fovy / 2)``,
``tan_x = aspect · tan_y``, ``d = margin · max_p (max(|x| / tan_x, |y| / tan_y) - z)``, at least
1.05 times the box's half-diagonal. Camera dicts have the keys ``lookat``, ``distance``,
``azimuth``, ``elevation``, or name a model camera with ``{"name": "track"}``.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from robovae.data.loading import robot_root

__all__ = ["DEFAULT_AZIMUTH", "DEFAULT_ELEVATION", "auto_camera", "camera_axes", "mjv_camera",
           "resolve_camera", "robot_bounds", "robot_points"]

#: Default camera azimuth (degrees).
DEFAULT_AZIMUTH = 135.0
#: Default camera elevation (degrees; negative looks down).
DEFAULT_ELEVATION = -20.0

_PLANE = mujoco.mjtGeom.mjGEOM_PLANE
_HFIELD = mujoco.mjtGeom.mjGEOM_HFIELD


def robot_points(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """World corners of the robot's geom AABBs (planes and height fields excluded) and its body
    positions, ``[P, 3]`` (finite rows only; one origin row when there is none)."""
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
    (:func:`robovae.data.loading.robot_root`): props such as balls and targets are left out.
    """
    pts = robot_points(model, data)
    return pts.min(axis=0), pts.max(axis=0)


def camera_axes(azimuth: float, elevation: float) -> tuple[np.ndarray, ...]:
    """MuJoCo's free-camera ``(forward, up, right)`` unit vectors for angles in degrees:
    ``forward = (cos e cos a, cos e sin a, sin e)``, ``up = (-sin e cos a, -sin e sin a, cos e)``,
    ``right = forward × up``."""
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
    pts = robot_points(model, data)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = 0.5 * (lo + hi)
    forward, up, right = camera_axes(azimuth, elevation)
    rel = pts - centre
    x, y, z = rel @ right, rel @ up, rel @ forward
    tan_y = math.tan(math.radians(model.vis.global_.fovy) / 2.0)
    tan_x = tan_y * aspect
    need = np.maximum(np.abs(x) / tan_x, np.abs(y) / tan_y) - z
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    distance = max(float(need.max()) * margin, radius * 1.05, 1e-4)
    return {"lookat": centre.tolist(), "distance": distance, "azimuth": float(azimuth),
            "elevation": float(elevation)}


def resolve_camera(model: mujoco.MjModel, data: mujoco.MjData, camera: dict | None,
                   aspect: float) -> dict[str, Any]:
    """The camera dict to render with: ``{"name": ...}`` as given; otherwise
    :func:`auto_camera` (at the given or default angles) updated with the given keys."""
    camera = dict(camera or {})
    if "name" in camera:
        return camera
    auto = auto_camera(model, data,
                       azimuth=camera.get("azimuth", DEFAULT_AZIMUTH),
                       elevation=camera.get("elevation", DEFAULT_ELEVATION), aspect=aspect)
    auto.update(camera)
    return auto


def mjv_camera(model: mujoco.MjModel, camera: dict[str, Any]) -> mujoco.MjvCamera | int:
    """A camera dict as ``mujoco.Renderer.update_scene`` takes it: a model camera id, or a free
    ``MjvCamera``.

    Raises:
        ValueError: no model camera of that name, or keys other than ``lookat``, ``distance``,
            ``azimuth``, ``elevation``.
    """
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
