"""``robovae/Walk-v0``: a Gymnasium walking task for any robot file.

:class:`WalkEnv` subclasses :class:`gymnasium.envs.mujoco.MujocoEnv` (same ``frame_skip``,
``dt``, ``reset_model`` / ``set_state`` / ``do_simulation`` conventions and renderer). The robot
file is loaded with :func:`robovae.data.mjcf.load_robot` (Menagerie files without their meshes
load) and turned into a scene with ``mujoco.MjSpec`` edits, never XML strings:

- **floor**: when the model has no floor (a world plane or height field), a checkered plane is
  added (:func:`robovae.evaluate.scene.add_floor`) at the robot's lowest point in its initial
  pose (below); a light is added when the model has none.
- **root**: the robot is the top-level body with the largest subtree
  (:func:`robovae.data.loading.robot_root`). A root body **without any joint** (welded to the world,
  e.g. an arm) gets a free joint when ``free_base`` (default): it then falls onto the floor and
  can walk if its body allows (its keyframes get the free joint's coordinates, the pose as
  written, in their place). With ``free_base=False`` it stays fixed: the root never moves, so
  the forward velocity is always 0, the robot is always healthy and the only reward terms are
  the health bonus and the control cost (useful for reaching, or to check a policy's plumbing).
  A root with hinge/slide joints (planar robots such as the half-cheetah) is kept as it is.
- **actuators**: every actuator of the file is an action. A robot without actuators cannot
  walk: :class:`~robovae.errors.RobovaeError` ``robovae: <file>: no actuators to walk with
  (actuator)``; nor can a robot with an **actuated base**, a motor on a joint between its root
  body and the world (:func:`~robovae.evaluate.quality.locomotion.actuated_base`: a gantry that
  carries the root, not legs): ``robovae: <file>: a motor moves its root body relative to the
  world (actuated base), nothing to walk with (actuator)``.

**Initial pose**: the robot's rest pose (:func:`robovae.evaluate.quality.stage.rest_pose`: its
``home`` keyframe when it has one, as a generated robot's balanced stance,
:mod:`robovae.generate.bipeds`; else ``qpos0``; joints clipped into their ranges), at rest;
``reset`` adds noise to it.

**Actions** lie in ``[-1, 1]^nu`` (``float32``) and are scaled to each actuator's control range
``[lo, hi]``: ``ctrl = lo + (a + 1) (hi - lo) / 2``; an actuator without ``ctrlrange``
(``ctrllimited="false"``) uses ``[-1, 1]``.

**Observation** (``float64``), in three blocks (:attr:`WalkEnv.layout` gives their sizes):

1. root state, 10 values: height of the root body above the floor (m); gravity direction in the
   root frame (3, unit); root linear velocity in the root frame (3, m/s); root angular velocity
   in the root frame (3, rad/s);
2. joint positions: ``qpos`` of every joint except the free joint of the root and the slide
   joints of the root body (its world translation; as Gymnasium's
   ``exclude_current_positions_from_observation``), ball joints as 4 quaternion values;
3. joint velocities: ``qvel`` of the same joints (ball joints: 3).

**Reward** per step of ``dt = frame_skip · timestep`` seconds::

    r = forward_reward_weight · v_fwd + healthy_reward · healthy - ctrl_cost_weight · mean(a²)

where ``v_fwd = (p_after - p_before) · h / dt`` is the root body's velocity along its **heading**
``h``, the horizontal unit projection of the root's local ``x`` axis at the start of the step
(world ``x`` when that axis is vertical), ``p`` the root body's world position; ``a`` the
normalised action (so the cost does not depend on the actuators' ranges or count).

**Health**: the robot is healthy when the state is finite, MuJoCo raised no instability warning
during the step, the root height above the floor is at least ``min_height_ratio`` times its
height in the initial pose, and the root's up axis (the local direction that points up in it) is
within ``max_tilt`` degrees of vertical. With ``terminate_when_unhealthy`` an unhealthy step
ends the episode (``terminated``); the registered env truncates after 1000 steps.

``info`` holds ``x_velocity`` (world x, m/s), ``forward_velocity``, ``height``, ``upright``
(cosine of the tilt), ``healthy``, ``reward_forward``, ``reward_ctrl``, ``reward_survive``.

Raises (constructor): :class:`~robovae.errors.RobotFileError` for a file that is not a robot,
:class:`~robovae.errors.RobovaeError` for a robot without actuators or bad settings.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.envs.mujoco.mujoco_env import MujocoEnv

from robovae.data.loading import capture_mujoco_warnings, load_robot, quiet_forward, robot_root
from robovae.errors import RobovaeError
from robovae.evaluate.camera import robot_bounds
from robovae.evaluate.quality.locomotion import actuated_base
from robovae.evaluate.quality.stage import rest_pose
from robovae.evaluate.scene import add_floor, has_floor
from robovae.settings import FINITE, check_settings, integer, number

__all__ = ["ROOT_DIM", "Layout", "WalkEnv", "walk_scene"]

#: Size of the root-state block of the observation.
ROOT_DIM = 10

_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
#: ``render_mode="human"`` opens a window: offered only when there is a display to open it on
_HAS_DISPLAY = bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
_BAD = (mujoco.mjtWarning.mjWARN_BADQACC, mujoco.mjtWarning.mjWARN_BADQPOS,
        mujoco.mjtWarning.mjWARN_BADQVEL)


@dataclass(frozen=True)
class Layout:
    """Sizes of a robot's observation blocks and action.

    Attributes:
        qpos: joint-position block size. qvel: joint-velocity block size. action: actuators.
    """

    qpos: int
    qvel: int
    action: int

    @property
    def obs(self) -> int:
        """Observation size: ``ROOT_DIM + qpos + qvel``."""
        return ROOT_DIM + self.qpos + self.qvel


@dataclass
class _Scene:
    model: mujoco.MjModel
    root: int
    floor_z: float
    size: float
    qpos_idx: np.ndarray
    qvel_idx: np.ndarray


def _root_body(spec: mujoco.MjSpec, root: int) -> mujoco.MjsBody:
    return spec.bodies[root]  # spec bodies are in compiled (depth-first) order, world first


def _compile(spec: mujoco.MjSpec) -> mujoco.MjModel:
    with capture_mujoco_warnings():
        return spec.compile()


def _joint_indices(model: mujoco.MjModel, root: int) -> tuple[np.ndarray, np.ndarray]:
    """``qpos`` / ``qvel`` indices of the observed joints (module docstring)."""
    qpos: list[int] = []
    qvel: list[int] = []
    for j in range(model.njnt):
        jtype = int(model.jnt_type[j])
        if jtype == _FREE or (jtype == _SLIDE and model.jnt_bodyid[j] == root):
            continue
        nq = {int(mujoco.mjtJoint.mjJNT_BALL): 4}.get(jtype, 1)
        nv = 3 if nq == 4 else 1
        qpos += range(model.jnt_qposadr[j], model.jnt_qposadr[j] + nq)
        qvel += range(model.jnt_dofadr[j], model.jnt_dofadr[j] + nv)
    return np.array(qpos, dtype=int), np.array(qvel, dtype=int)


def _free_root(spec: mujoco.MjSpec, model: mujoco.MjModel, root: int) -> mujoco.MjModel:
    """Give the jointless root body ``root`` a free joint and compile. A keyframe written for
    the fixed robot (``nq`` positions, ``nv`` velocities) gets the root's pose (its ``qpos0``)
    and a zero velocity inserted where the free joint's coordinates go, so its joint values
    stay on their joints (MuJoCo would pad the key at the end and shift them)."""
    # read before compiling: the compiler pads the spec's keys to the new sizes
    keys = [(np.array(k.qpos, float), np.array(k.qvel, float)) for k in spec.keys]
    _root_body(spec, root).add_freejoint()
    new = _compile(spec)
    q, d = int(new.jnt_qposadr[new.body_jntadr[root]]), int(new.jnt_dofadr[new.body_jntadr[root]])
    for key, (qpos, qvel) in zip(spec.keys, keys):
        if len(qpos) == model.nq:
            key.qpos = np.insert(qpos, q, new.qpos0[q:q + 7])
        if len(qvel) == model.nv:
            key.qvel = np.insert(qvel, d, np.zeros(6))
    return _compile(spec)


def walk_scene(robot: str | os.PathLike, free_base: bool = True) -> tuple[mujoco.MjSpec, _Scene]:
    """The robot's spec with floor, light and (``free_base``) a free joint on a jointless root
    (module docstring), and facts about it.

    Raises:
        RobotFileError: the file cannot be loaded.
        RobovaeError: the robot has no actuators, or an actuated base.
    """
    path = Path(robot)
    loaded = load_robot(path)
    spec, model = loaded.spec, loaded.model
    if model.nu == 0:
        raise RobovaeError(f"robovae: {path}: no actuators to walk with (actuator)")
    root, _ = robot_root(model)
    if actuated_base(model, root):
        raise RobovaeError(f"robovae: {path}: a motor moves its root body relative to the world "
                           "(actuated base), nothing to walk with (actuator)")
    if free_base and model.body_jntnum[root] == 0:
        model = _free_root(spec, model, root)
    data = mujoco.MjData(model)
    data.qpos[:] = rest_pose(model)
    quiet_forward(model, data)
    lo, hi = robot_bounds(model, data)
    floor = has_floor(model)
    if not floor:
        add_floor(spec, light=model.nlight == 0, skybox=False)
        spec.geom("robovae_floor").pos = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]),
                                          float(lo[2])]
    elif model.nlight == 0:
        spec.worldbody.add_light(name="robovae_sun", pos=[0.0, 0.0, float(hi[2]) + 4.0],
                                 dir=[0.0, 0.0, -1.0])
    model = _compile(spec)
    floor_z = float(lo[2]) if not floor else _floor_below(model, float(lo[2]))
    qpos_idx, qvel_idx = _joint_indices(model, root)
    size = float(np.linalg.norm(hi - lo))
    return spec, _Scene(model, root, floor_z, max(size, 1e-6), qpos_idx, qvel_idx)


def _floor_below(model: mujoco.MjModel, lowest: float) -> float:
    """Height of the highest upward-facing world plane not above ``lowest`` (``lowest`` when
    the floor is a height field or a tilted plane)."""
    data = mujoco.MjData(model)
    quiet_forward(model, data)
    plane = int(mujoco.mjtGeom.mjGEOM_PLANE)
    z = [float(data.geom_xpos[g, 2]) for g in range(model.ngeom)
         if model.geom_bodyid[g] == 0 and model.geom_type[g] == plane
         and data.geom_xmat[g, 8] > 0.99 and data.geom_xpos[g, 2] <= lowest + 1e-3]
    return max(z) if z else lowest


class WalkEnv(MujocoEnv):
    """Walk forward with any robot (module docstring for observation, action, reward, health).

    Args:
        robot: MJCF or URDF file of the robot.
        frame_skip: physics steps per environment step.
        forward_reward_weight: weight of the heading-frame forward velocity (per m/s).
        healthy_reward: reward per healthy step.
        ctrl_cost_weight: weight of the mean squared normalised action.
        min_height_ratio: healthy root height, as a fraction of its height in the initial pose
            (in ``[0, 1]``: above 1 the robot is unhealthy where it starts).
        max_tilt: healthy tilt of the root's up axis from vertical (degrees, in ``(0, 180]``).
        terminate_when_unhealthy: end the episode at the first unhealthy step.
        reset_noise_scale: half-width of the uniform noise added to joint positions, and std of
            the normal noise of velocities, at reset (free-joint orientation left exact).
        free_base: give a jointless root a free joint (module docstring).
        render_mode: as :class:`~gymnasium.envs.mujoco.mujoco_env.MujocoEnv`; the default
            camera tracks the root body. ``"human"`` (a window) is listed in
            ``metadata["render_modes"]`` only when ``DISPLAY`` or ``WAYLAND_DISPLAY`` is set
            (off-screen modes use ``MUJOCO_GL``, e.g. ``egl``).
        width: render width (pixels).
        height: render height (pixels).

    Attributes:
        up_local: the root body's local direction that points up in the initial pose (its
            tilt from vertical is the health's tilt).
    """

    metadata = {"render_modes": (["human"] if _HAS_DISPLAY else [])
                + ["rgb_array", "depth_array", "rgbd_tuple"]}

    def __init__(self, robot: str | os.PathLike, frame_skip: int = 5,
                 forward_reward_weight: float = 1.0, healthy_reward: float = 1.0,
                 ctrl_cost_weight: float = 0.1, min_height_ratio: float = 0.3,
                 max_tilt: float = 60.0, terminate_when_unhealthy: bool = True,
                 reset_noise_scale: float = 0.05, free_base: bool = True,
                 render_mode: str | None = None, width: int = 480, height: int = 480) -> None:
        check_settings(
            "WalkEnv", frame_skip=(frame_skip, integer(1)),
            forward_reward_weight=(forward_reward_weight, FINITE),
            healthy_reward=(healthy_reward, FINITE), ctrl_cost_weight=(ctrl_cost_weight, number(0)),
            min_height_ratio=(min_height_ratio, number(0, 1)),
            max_tilt=(max_tilt, number(0, 180, low_open=True)),
            reset_noise_scale=(reset_noise_scale, number(0)), width=(width, integer(1)),
            height=(height, integer(1)))
        self.robot_path = Path(robot).resolve()
        self.spec_, self.scene = walk_scene(self.robot_path, free_base=free_base)
        model = self.scene.model
        self.forward_reward_weight = float(forward_reward_weight)
        self.healthy_reward_weight = float(healthy_reward)
        self.ctrl_cost_weight = float(ctrl_cost_weight)
        self.min_height_ratio = float(min_height_ratio)
        self.cos_max_tilt = math.cos(math.radians(max_tilt))
        self.terminate_when_unhealthy = bool(terminate_when_unhealthy)
        self.reset_noise_scale = float(reset_noise_scale)
        self.layout = Layout(len(self.scene.qpos_idx), len(self.scene.qvel_idx), model.nu)
        self.metadata = {**self.metadata,
                         "render_fps": int(round(1.0 / (model.opt.timestep * frame_skip)))}
        obs_space = spaces.Box(-np.inf, np.inf, (self.layout.obs,), np.float64)
        camera = {"trackbodyid": self.scene.root, "distance": 2.0 * self.scene.size,
                  "elevation": -20.0}
        super().__init__(str(self.robot_path), int(frame_skip), obs_space,
                         render_mode=render_mode, width=width, height=height,
                         default_camera_config=camera)
        lo, hi = model.actuator_ctrlrange.T.copy()
        unlimited = model.actuator_ctrllimited == 0
        lo[unlimited], hi[unlimited] = -1.0, 1.0
        self._ctrl_lo, self._ctrl_hi = lo, hi
        self.init_qpos = rest_pose(self.model)
        self.data.qpos[:] = self.init_qpos
        mujoco.mj_forward(self.model, self.data)
        root = self.scene.root
        self._init_height = float(self.data.xpos[root, 2]) - self.scene.floor_z
        self.up_local = self.data.xmat[root].reshape(3, 3).T @ np.array([0.0, 0.0, 1.0])

    # -- MujocoEnv hooks -------------------------------------------------------------------
    def _initialize_simulation(self) -> tuple[mujoco.MjModel, mujoco.MjData]:
        model = self.scene.model
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, self.height)
        return model, mujoco.MjData(model)

    def _set_action_space(self) -> spaces.Box:
        self.action_space = spaces.Box(-1.0, 1.0, (self.model.nu,), np.float32)
        return self.action_space

    def reset_model(self) -> np.ndarray:
        """Initial pose plus noise on the observed joints (see ``reset_noise_scale``)."""
        s = self.reset_noise_scale
        qpos, qvel = self.init_qpos.copy(), self.init_qvel.copy()
        qi, vi = self.scene.qpos_idx, self.scene.qvel_idx
        qpos[qi] += self.np_random.uniform(-s, s, len(qi))
        qvel[vi] += s * self.np_random.standard_normal(len(vi))
        self.set_state(qpos, qvel)
        self._warnings = self._warning_count()
        return self._get_obs()

    # -- task --------------------------------------------------------------------------------
    def scale_action(self, action: np.ndarray) -> np.ndarray:
        """Controls for a normalised action: ``lo + (a + 1) (hi - lo) / 2`` (clipped to
        ``[-1, 1]`` first)."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        return self._ctrl_lo + 0.5 * (a + 1.0) * (self._ctrl_hi - self._ctrl_lo)

    def _warning_count(self) -> int:
        return sum(int(self.data.warning[w].number) for w in _BAD)

    def _heading(self) -> np.ndarray:
        x = self.data.xmat[self.scene.root].reshape(3, 3)[:, 0].copy()
        x[2] = 0.0
        n = float(np.linalg.norm(x))
        return x / n if n > 1e-6 else np.array([1.0, 0.0, 0.0])

    def _root_state(self) -> np.ndarray:
        root = self.scene.root
        rot = self.data.xmat[root].reshape(3, 3)
        vel = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, root, vel, 1)
        height = float(self.data.xpos[root, 2]) - self.scene.floor_z
        gravity = rot.T @ np.array([0.0, 0.0, -1.0])
        return np.concatenate([[height], gravity, vel[3:], vel[:3]])

    def _get_obs(self) -> np.ndarray:
        return np.concatenate([self._root_state(), self.data.qpos[self.scene.qpos_idx],
                               self.data.qvel[self.scene.qvel_idx]]).astype(np.float64)

    def _health(self) -> tuple[bool, float, float]:
        root = self.scene.root
        height = float(self.data.xpos[root, 2]) - self.scene.floor_z
        up = float((self.data.xmat[root].reshape(3, 3) @ self.up_local)[2])
        finite = bool(np.isfinite(self.data.qpos).all() and np.isfinite(self.data.qvel).all())
        stable = self._warning_count() == self._warnings
        healthy = (finite and stable and up >= self.cos_max_tilt
                   and height >= self.min_height_ratio * self._init_height)
        return healthy, height, up

    # MujocoEnv.step's annotation (float64 reward, float64-only info) is narrower than the
    # gymnasium.Env.step contract (SupportsFloat reward, dict[str, Any] info) this follows
    def step(  # type: ignore[override]
            self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """One step of ``dt`` seconds (module docstring for the reward and termination)."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        root = self.scene.root
        before, heading = self.data.xpos[root].copy(), self._heading()
        self.do_simulation(self.scale_action(a), self.frame_skip)
        delta = (self.data.xpos[root] - before) / self.dt
        v_fwd = float(delta @ heading)
        healthy, height, up = self._health()
        forward = self.forward_reward_weight * v_fwd
        ctrl = self.ctrl_cost_weight * float(np.mean(a ** 2)) if a.size else 0.0
        survive = self.healthy_reward_weight * float(healthy)
        reward = forward + survive - ctrl
        terminated = self.terminate_when_unhealthy and not healthy
        obs = self._get_obs()
        if not np.isfinite(obs).all():  # diverged: report it and end, never emit NaN
            obs, reward, terminated = np.nan_to_num(obs, posinf=0.0, neginf=0.0), 0.0, True
        info = {"x_velocity": float(delta[0]), "forward_velocity": v_fwd, "height": height,
                "upright": up, "healthy": healthy, "reward_forward": forward,
                "reward_ctrl": -ctrl, "reward_survive": survive}
        if self.render_mode == "human":
            self.render()
        return obs, float(reward), bool(terminated), False, info
