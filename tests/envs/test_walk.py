"""robovae/Walk-v0: registration, check_env, spaces, reward, health, bad robots, vector env."""

from __future__ import annotations

from pathlib import Path

import gymnasium
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import robovae.envs
from robovae.data.procedural import procedural_spec
from robovae.envs.vector import make_vector_env, robot_files
from robovae.envs.walk import ROOT_DIM, WalkEnv
from robovae.errors import RobotFileError, RobovaeError


def write(spec: mujoco.MjSpec, path) -> str:
    path.write_text(spec.to_xml())
    return str(path)


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    """Three procedural robots of different sizes (a quadruped, a hexapod, a humanoid)."""
    root = tmp_path_factory.mktemp("robots")
    return [write(procedural_spec(i, kind=k), root / f"{k}.xml")
            for i, k in enumerate(["quadruped", "hexapod", "humanoid"])]


def test_registered_and_passes_check_env(robots):
    assert robovae.envs.WALK_ID in gymnasium.registry
    env = gymnasium.make("robovae/Walk-v0", robot=robots[0])
    assert env.spec.max_episode_steps == 1000
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_spaces_follow_the_robot(robots):
    env = WalkEnv(robots[1])
    m = env.unwrapped.model
    assert env.action_space.shape == (m.nu,) and env.action_space.dtype == np.float32
    assert float(env.action_space.low.min()) == -1.0 and float(env.action_space.high.max()) == 1
    free = sum(m.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    assert env.layout.qpos == m.nq - 7 * free and env.layout.qvel == m.nv - 6 * free
    obs, _ = env.reset(seed=0)
    assert obs.shape == (ROOT_DIM + env.layout.qpos + env.layout.qvel,)
    assert obs.dtype == np.float64 and env.observation_space.contains(obs)
    assert obs[0] == pytest.approx(env._init_height, abs=0.05)      # root height above floor
    np.testing.assert_allclose(obs[1:4], [0, 0, -1], atol=1e-6)       # gravity in root frame


def test_actions_scale_to_ctrlrange(robots):
    env = WalkEnv(robots[0])
    lo, hi = env.model.actuator_ctrlrange.T
    np.testing.assert_allclose(env.scale_action(-np.ones(env.model.nu)), lo)
    np.testing.assert_allclose(env.scale_action(np.ones(env.model.nu)), hi)
    np.testing.assert_allclose(env.scale_action(np.zeros(env.model.nu)), (lo + hi) / 2)
    env.reset(seed=0)
    env.step(np.ones(env.model.nu, dtype=np.float32))
    np.testing.assert_allclose(env.data.ctrl, hi)


def test_reward_is_forward_velocity_in_heading_frame(robots):
    """Pushing the robot along its heading pays; the same push backwards costs."""
    rewards = []
    for sign in (1.0, -1.0):
        env = WalkEnv(robots[0], reset_noise_scale=0.0, ctrl_cost_weight=0.0, healthy_reward=0.0)
        env.reset(seed=0)
        heading = env._heading()
        qvel = env.data.qvel.copy()
        qvel[:3] = sign * 0.5 * heading  # free joint linear velocity (world frame)
        env.set_state(env.data.qpos.copy(), qvel)
        _, r, _, _, info = env.step(np.zeros(env.model.nu, dtype=np.float32))
        assert r == pytest.approx(info["forward_velocity"])
        rewards.append(r)
    assert rewards[0] > 0.2 and rewards[1] < -0.2


def test_falling_robot_is_unhealthy_and_terminates(robots):
    env = WalkEnv(robots[2], reset_noise_scale=0.0)
    env.reset(seed=0)
    qpos = env.data.qpos.copy()
    qpos[3:7] = [np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0]  # tipped 90° about x
    env.set_state(qpos, env.data.qvel.copy())
    _, _, terminated, _, info = env.step(np.zeros(env.model.nu, dtype=np.float32))
    assert terminated and not info["healthy"] and info["upright"] < 0.5
    env2 = WalkEnv(robots[2], reset_noise_scale=0.0, terminate_when_unhealthy=False)
    env2.reset(seed=0)
    env2.set_state(qpos, env2.data.qvel.copy())
    assert env2.step(np.zeros(env2.model.nu, dtype=np.float32))[2] is False


def test_floor_and_light_are_added_once(robots, tmp_path):
    env = WalkEnv(robots[0])
    planes = env.model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE
    assert planes.sum() == 1 and env.model.nlight >= 1
    spec = procedural_spec(0)
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1], pos=[0, 0, -0.5])
    env2 = WalkEnv(write(spec, tmp_path / "floored.xml"))
    assert (env2.model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE).sum() == 1
    assert env2.scene.floor_z == pytest.approx(-0.5)


def fixed_arm() -> mujoco.MjSpec:
    spec = mujoco.MjSpec()
    base = spec.worldbody.add_body(name="base", pos=[0, 0, 0.1])
    base.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 0.05, 0.05])
    link = base.add_body(name="link", pos=[0, 0, 0.05])
    link.add_joint(name="j", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
    link.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[0, 0, 0, 0, 0, 0.3],
                  size=[0.02, 0, 0])
    spec.add_actuator(target="j", trntype=mujoco.mjtTrn.mjTRN_JOINT, ctrlrange=[-2, 2],
                      ctrllimited=mujoco.mjtLimited.mjLIMITED_TRUE)
    return spec


def test_jointless_root_gets_a_free_joint_or_stays_fixed(tmp_path):
    path = write(fixed_arm(), tmp_path / "arm.xml")
    free = WalkEnv(path)
    assert free.model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    fixed = WalkEnv(path, free_base=False)
    assert fixed.model.njnt == 1 and fixed.layout.qpos == 1
    check_env(fixed, skip_render_check=True)
    fixed.reset(seed=0)
    for _ in range(20):
        _, r, terminated, _, info = fixed.step(fixed.action_space.sample())
        assert info["forward_velocity"] == pytest.approx(0.0, abs=1e-9) and not terminated


def test_a_fixed_robots_home_keyframe_keeps_its_joint_values_with_a_free_base(tmp_path):
    spec = fixed_arm()
    spec.add_key(name="home", qpos=[0.7], qvel=[0.0])
    env = WalkEnv(write(spec, tmp_path / "arm.xml"))
    assert env.model.nq == 8 and env.model.key_qpos.shape == (1, 8)
    assert env.init_qpos[7] == pytest.approx(0.7)  # the hinge's home value on the hinge
    assert env.init_qpos[3:7] == pytest.approx([1, 0, 0, 0])  # the base as written, upright
    assert env.init_qpos[:2] == pytest.approx([0, 0])
    env.reset(seed=0)
    assert np.isfinite(env.step(np.zeros(1))[0]).all()


def test_bad_robots_raise_one_line(tmp_path):
    spec = procedural_spec(0)
    for a in list(spec.actuators):
        spec.delete(a)
    no_act = write(spec, tmp_path / "passive.xml")
    with pytest.raises(RobovaeError, match=r"passive.xml: no actuators to walk with"):
        gymnasium.make("robovae/Walk-v0", robot=no_act)
    gantry = mujoco.MjSpec()  # a box carried by motors on its slides to the world
    body = gantry.worldbody.add_body(name="cart", pos=[0, 0, 0.1])
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.1, 0.1, 0.1])
    for name, axis in (("x", [1, 0, 0]), ("z", [0, 0, 1])):
        body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=axis)
        gantry.add_actuator(target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    with pytest.raises(RobovaeError, match=r"gantry.xml: a motor moves its root body .* "
                       r"\(actuated base\)"):
        WalkEnv(write(gantry, tmp_path / "gantry.xml"))
    junk = tmp_path / "junk.xml"
    junk.write_text("this is not a robot")
    with pytest.raises(RobotFileError) as e:
        WalkEnv(junk)
    assert "\n" not in str(e.value) and "junk.xml" in str(e.value)


@pytest.mark.parametrize("kw, match", [
    ({"frame_skip": 0}, r"WalkEnv\.frame_skip must be an integer >= 1, got 0"),
    ({"max_tilt": 200.0}, r"max_tilt must be a number in \(0, 180\], got 200"),
    # accepted before 2026-11-29: unhealthy from the start, every episode one step long
    ({"max_tilt": 0.0}, r"max_tilt must be a number in \(0, 180\], got 0"),
    ({"min_height_ratio": 1.5}, r"min_height_ratio must be a number in \[0, 1\], got 1.5"),
    ({"reset_noise_scale": -0.1}, "reset_noise_scale must be a number >= 0"),
    ({"width": -5, "render_mode": "rgb_array"}, "width must be an integer >= 1, got -5"),
    # accepted before 2026-11-29: NaN rewards, a frame skip of 2.5 taken as 2
    ({"ctrl_cost_weight": float("nan")}, "ctrl_cost_weight must be a number >= 0, got nan"),
    ({"healthy_reward": float("inf")}, "healthy_reward must be a finite number, got inf"),
    ({"frame_skip": 2.5}, "frame_skip must be an integer >= 1, got 2.5"),
])
def test_bad_settings_raise_one_line(robots, kw, match):
    with pytest.raises(RobovaeError, match=match) as e:
        gymnasium.make("robovae/Walk-v0", robot=robots[0], **kw)
    assert "\n" not in str(e.value) and isinstance(e.value, ValueError)


def test_settings_take_numpy_integers(robots):
    env = WalkEnv(robots[0], frame_skip=np.int64(2), forward_reward_weight=-1.0)
    assert env.frame_skip == 2
    env.close()


def test_render_rgb_array(robots):
    env = WalkEnv(robots[0], render_mode="rgb_array", width=64, height=48)
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (48, 64, 3) and img.std() > 1.0
    env.close()


def test_vector_env_pads_and_masks(robots, tmp_path):
    venv = make_vector_env(robots, asynchronous=False)
    sizes = [lay.obs for lay in venv.layouts]
    assert venv.obs_mask.sum(1).tolist() == sizes
    assert venv.action_mask.sum(1).tolist() == [lay.action for lay in venv.layouts]
    obs, _ = venv.reset(seed=0)
    assert obs.shape == (3, venv.obs_mask.shape[1])
    assert np.all(obs[~venv.obs_mask] == 0)
    for _ in range(5):
        obs, r, term, trunc, _ = venv.step(venv.action_space.sample())
        assert np.all(obs[~venv.obs_mask] == 0) and np.isfinite(r).all()
    # the real entries are the robot's own observation
    single = WalkEnv(robots[1])
    own, _ = single.reset(seed=1)
    venv.reset(seed=0)
    assert np.allclose(venv.reset(seed=[0, 1, 2])[0][1][venv.obs_mask[1]], own)
    venv.close()


def test_async_vector_env_steps(robots):
    venv = make_vector_env(robots[:2], context="fork")
    venv.reset(seed=0)
    for _ in range(10):
        _, r, _, _, _ = venv.step(venv.action_space.sample())
    assert r.shape == (2,)
    venv.close()


def test_robot_files_of_a_generate_folder(tmp_path, robots):
    for i in (1, 0):
        (tmp_path / f"robot_{i:06d}").mkdir()
        (tmp_path / f"robot_{i:06d}" / "robot.xml").write_text(Path(robots[i]).read_text())
    assert [p.parent.name for p in robot_files(tmp_path)] == ["robot_000000", "robot_000001"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(RobovaeError, match=r"empty: no robot files \(robot.xml, robot_"):
        robot_files(tmp_path / "empty")
    with pytest.raises(RobovaeError, match="not a folder"):
        robot_files(tmp_path / "missing")
