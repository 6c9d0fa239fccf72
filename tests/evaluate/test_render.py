"""Off-screen renders, contact sheets and side-by-sides (robovae.evaluate.render), the scene
and camera they use, and tree drawings (robovae.evaluate.graph_drawing)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import torch
from PIL import Image

from robovae.data.features import get_feature_set
from robovae.data.graph import tree_data
from robovae.data.loading import load_robot
from robovae.data.zoo import zoo_files
from robovae.errors import RobovaeError
from robovae.evaluate import render as R
from robovae.evaluate.camera import auto_camera, camera_axes, robot_bounds, robot_points
from robovae.evaluate.graph_drawing import draw_graph, tree_layout
from robovae.evaluate.quality.stage import rest_pose
from robovae.evaluate.scene import prepare, scene_option

REPO = Path(__file__).resolve().parents[2]
GO2 = REPO.parent / "shared" / "menagerie" / "unitree_go2" / "go2.xml"


def _zoo(name: str) -> Path:
    files = dict(zoo_files()[0])
    if name not in files:
        pytest.skip(f"zoo model {name} not installed")
    return files[name]


def _legged_spec(scale: float = 1.0, leg_geoms: bool = True) -> mujoco.MjSpec:
    """A box torso on a free joint with four two-segment legs (geom-less legs optional)."""
    spec = mujoco.MjSpec()
    spec.modelname = "legged"
    torso = spec.worldbody.add_body(name="torso", pos=[0, 0, 0.8 * scale])
    torso.add_freejoint()
    torso.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.2 * scale, 0.1 * scale, 0.05 * scale])
    for sx in (-1, 1):
        for sy in (-1, 1):
            hip = torso.add_body(pos=[0.2 * sx * scale, 0.1 * sy * scale, 0])
            hip.add_joint(axis=[0, 1, 0])
            knee = hip.add_body(pos=[0.1 * sx * scale, 0.1 * sy * scale, -0.35 * scale])
            knee.add_joint(axis=[0, 1, 0])
            for body in (hip, knee):
                body.mass, body.inertia, body.explicitinertial = 0.1, [1e-3] * 3, True
            if leg_geoms:
                hip.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.03 * scale, 0, 0],
                             fromto=[0, 0, 0, 0.1 * sx * scale, 0.1 * sy * scale, -0.35 * scale])
                knee.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.03 * scale, 0, 0],
                              fromto=[0, 0, 0, 0, 0, -0.4 * scale])
    return spec


@pytest.fixture(scope="module", autouse=True)
def gl_available() -> None:
    """Skip the module when no off-screen GL context can be made (e.g. no EGL/OSMesa)."""
    try:
        R.render_robot(_legged_spec(), 32, 24)
    except RuntimeError as e:
        pytest.skip(str(e))


def _forward(model: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return data


def _not_blank(img: np.ndarray, height: int, width: int) -> None:
    assert img.shape == (height, width, 3)
    assert img.dtype == np.uint8
    assert img.reshape(-1, 3).std(axis=0).mean() > 10.0


def test_render_ant_differs_from_empty_scene() -> None:
    ant = _zoo("gym_ant")
    img = R.render_robot(ant)
    _not_blank(img, 360, 480)
    camera = R.robot_camera(ant)
    # the same scene (ant.xml's own floor) without the robot, from the same camera
    empty = load_robot(ant).spec
    for item in (*empty.actuators, *empty.worldbody.bodies):
        empty.delete(item)
    background = R.render_robot(empty, camera=camera)
    changed = np.abs(img.astype(int) - background.astype(int)).sum(axis=2) > 30
    assert changed.mean() > 0.05, "the robot covers too few pixels"
    centre = changed[120:240, 160:320]
    assert centre.mean() > 0.3, "the robot is not in the middle of the picture"


def test_render_sizes_camera_overrides_and_errors() -> None:
    spec = _legged_spec()
    ngeom = len(spec.geoms)
    small = R.render_robot(spec, 160, 100)
    _not_blank(small, 100, 160)
    assert len(spec.geoms) == ngeom, "the caller's spec must not change"
    big = R.render_robot(spec, 800, 600)  # above MuJoCo's default 640x480 off-screen buffer
    _not_blank(big, 600, 800)
    side = R.render_robot(spec, 160, 100, camera={"azimuth": 45.0, "elevation": -5.0})
    assert not np.array_equal(side, small)
    with pytest.raises(ValueError, match="no camera named"):
        R.render_robot(spec, 64, 48, camera={"name": "missing"})
    with pytest.raises(ValueError, match="unknown camera keys"):
        R.render_robot(spec, 64, 48, camera={"zoom": 2})


def test_auto_camera_fits_the_robot_at_any_scale() -> None:
    for scale in (0.01, 1.0, 30.0):
        spec = _legged_spec(scale)
        model = spec.compile()
        cam = auto_camera(model)
        assert cam["azimuth"] == 135.0 and cam["elevation"] == -20.0
        assert 0.5 * scale < cam["distance"] < 5.0 * scale
        data = _forward(model)
        lo, hi = robot_bounds(model, data)
        np.testing.assert_allclose(cam["lookat"], 0.5 * (lo + hi))
        # every bounding point projects inside the view, and the robot fills a good part of it
        forward, up, right = camera_axes(cam["azimuth"], cam["elevation"])
        rel = robot_points(model, data) - np.asarray(cam["lookat"])
        depth = cam["distance"] + rel @ forward
        tan_y = np.tan(np.radians(model.vis.global_.fovy) / 2)
        u = np.abs(rel @ right) / depth / (tan_y * 4 / 3)
        v = np.abs(rel @ up) / depth / tan_y
        assert (depth > 0).all() and max(u.max(), v.max()) <= 1.0
        assert max(u.max(), v.max()) > 0.7
        _not_blank(R.render_robot(spec, 120, 90), 90, 120)


def test_bare_model_gets_a_scene_floor_and_is_not_changed() -> None:
    model = _legged_spec().compile()
    assert model.nlight == 0
    img = R.render_robot(model, 800, 600)
    _not_blank(img, 600, 800)
    assert model.vis.global_.offwidth == 640  # rendered from a copy
    no_floor = R.render_robot(model, 160, 120, floor=False)
    with_floor = R.render_robot(model, 160, 120)
    assert not np.array_equal(no_floor, with_floor)
    with pytest.warns(UserWarning, match="settle_seconds ignored"):
        R.render_robot(model, 64, 48, settle_seconds=0.1)


def test_a_robot_is_pictured_in_its_clipped_rest_pose() -> None:
    """The picture shows the pose the quality measures start from: knees whose range excludes
    0 are drawn clipped into it, not at qpos0."""
    spec = _legged_spec()
    spec.compiler.degree = False
    for joint in spec.joints[1:]:
        joint.range, joint.limited = [0.4, 0.8], mujoco.mjtLimited.mjLIMITED_TRUE
    prep = prepare(spec, 64, 48)
    assert prep.data.qpos[7] == pytest.approx(0.4)
    assert prep.data.qpos == pytest.approx(rest_pose(prep.model))
    bent = R.render_robot(spec, 160, 120)
    for joint in spec.joints[1:]:
        joint.range = [-0.8, 0.8]  # qpos0 inside the range: the legs straight
    assert not np.array_equal(bent, R.render_robot(spec, 160, 120))


def test_geomless_bodies_get_a_skeleton() -> None:
    spec = _legged_spec(leg_geoms=False)
    camera = R.robot_camera(spec)
    bones = R.render_robot(spec, 160, 120, camera=camera)
    plain = R.render_robot(spec, 160, 120, camera=camera, skeleton=False)
    assert (np.abs(bones.astype(int) - plain.astype(int)).sum(axis=2) > 30).mean() > 0.005


def test_settle_on_the_added_floor() -> None:
    spec = _legged_spec()
    img = R.render_robot(spec, 160, 120, settle_seconds=0.5)
    _not_blank(img, 120, 160)
    assert not np.array_equal(img, R.render_robot(spec, 160, 120))


@pytest.mark.skipif(not GO2.is_file(), reason=f"{GO2} not present")
def test_render_menagerie_go2_without_meshes() -> None:
    img = R.render_robot(GO2, 240, 180, settle_seconds=0.2)
    _not_blank(img, 180, 240)
    # only collision geoms are left (group 3): they are shown
    model = load_robot(GO2).model
    assert scene_option(model).geomgroup[3] == 1


def test_save_png_round_trip(tmp_path: Path) -> None:
    img = (np.arange(24 * 32 * 3) % 251).astype(np.uint8).reshape(24, 32, 3)
    path = R.save_png(img, tmp_path / "sub" / "x.png")
    np.testing.assert_array_equal(np.asarray(Image.open(path).convert("RGB")), img)


def test_contact_sheet(tmp_path: Path) -> None:
    items = [_zoo("gym_ant"), _legged_spec(), _legged_spec(0.1).compile()]
    out = R.contact_sheet(items, tmp_path / "sheet.png", columns=2, size=(160, 120),
                          labels=["ant", "legged", "tiny"])
    assert out.is_file()
    with Image.open(out) as im:
        assert im.size == (320, 240)
        sheet = np.asarray(im.convert("RGB"))
    assert sheet[121:, 161:].std() < 1.0  # the empty fourth tile stays plain
    one_row = R.contact_sheet(items, tmp_path / "row.png", size=(80, 60), max_items=2)
    with Image.open(one_row) as im:
        assert im.size == (160, 60)


def test_contact_sheet_bad_file_gets_a_tile(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.warns(UserWarning, match=r"tile 1 \(bad\) left grey: .*bad.xml: malformed"):
        out = R.contact_sheet([_legged_spec(), bad], tmp_path / "s.png", size=(80, 60),
                              labels=["good", "bad"])
    with Image.open(out) as im:
        assert im.size == (160, 60)


def test_contact_sheet_of_no_drawable_robot_is_an_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(RobovaeError, match=r"no robot drawn.*tile 0 \(bad\) left grey.*bad.xml"):
        R.contact_sheet([bad, bad], tmp_path / "s.png", size=(80, 60))
    assert not (tmp_path / "s.png").exists()


def test_contact_sheet_too_large_is_refused_before_rendering(tmp_path: Path) -> None:
    """Over MAX_SHEET_PIXELS nothing is drawn (the missing files are never opened)."""
    missing = [tmp_path / f"r{k}.xml" for k in range(51)]
    with pytest.raises(RobovaeError, match=r"51 robots of 1000x1000 px .* at most 50 \(render "
                       r"--first\); nothing written"):
        R.contact_sheet(missing, tmp_path / "s.png", size=(1000, 1000))
    assert not (tmp_path / "s.png").exists()


def test_contact_sheet_settings_are_checked_before_rendering(tmp_path: Path) -> None:
    """A tile size of -5 px was a NumPy traceback after the check of the sheet's size, and 0
    columns drew one (until 2026-11-29)."""
    missing = [tmp_path / "r.xml"]
    for bad, message in (({"size": (-5, 60)}, "contact_sheet.width must be an integer >= 1"),
                         ({"columns": 0}, "contact_sheet.columns must be an integer >= 1"),
                         ({"settle_seconds": -1.0}, "settle_seconds must be a number >= 0")):
        with pytest.raises(ValueError, match=message):
            R.contact_sheet(missing, tmp_path / "s.png", **bad)
    assert not (tmp_path / "s.png").exists()


def test_side_by_side(tmp_path: Path) -> None:
    out = R.side_by_side(_legged_spec(), _legged_spec(leg_geoms=False), tmp_path / "sbs.png",
                         size=(200, 150))
    with Image.open(out) as im:
        assert im.size == (400, 150)
        pair = np.asarray(im.convert("RGB")).astype(int)
    assert np.abs(pair[:, :200] - pair[:, 200:]).sum(axis=2).mean() > 1.0


def _small_tree():
    # link 0 ─ joint 1 ─ link 2 ─ geom 3
    #        ├ geom 4
    #        └ joint 5 ─ link 6
    parent = [-1, 0, 1, 2, 0, 0, 5]
    types = [0, 1, 0, 2, 2, 1, 0]
    fs = get_feature_set("full")
    return tree_data(parent, types, torch.zeros(7, fs.dim), fs, name="tiny")


def test_tree_layout_is_tidy() -> None:
    data = _small_tree()
    pos = tree_layout(data.parent)
    assert pos[0][1] == 0.0 and pos[3][1] == -3.0  # root on top, y = -depth
    leaves = [3, 4, 6]
    assert [pos[i][0] for i in leaves] == [0.0, 1.0, 2.0]
    assert pos[0][0] == pytest.approx(0.5 * (pos[1][0] + pos[5][0]))
    assert len({pos[i] for i in pos}) == len(pos)


def test_draw_graph(tmp_path: Path) -> None:
    data = _small_tree()
    out = draw_graph(data, tmp_path / "tree.png")
    assert out.is_file()
    with Image.open(out) as im:
        assert im.size[0] > 100 and im.size[1] > 100
    fig = draw_graph(data, title="mine")
    assert fig.axes[0].get_title() == "mine"
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["link (3)", "joint (2)", "geom (2)"]


def test_renderer_failure_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args, **kwargs):
        raise mujoco.FatalError("no OpenGL platform library")

    monkeypatch.setattr(mujoco, "Renderer", broken)
    with pytest.raises(RuntimeError, match=r"robovae: off-screen rendering unavailable "
                                           r"\(MUJOCO_GL=.*\): .*no OpenGL"):
        R.render_robot(_legged_spec(), 32, 24)


def test_mujoco_imported_before_the_module_still_renders() -> None:
    """``import mujoco`` before ``MUJOCO_GL`` is set makes MuJoCo pick GLFW; the module then
    switches to the headless backend it asked for."""
    code = ("import mujoco\n"
            "from robovae.evaluate.render import render_robot\n"
            "spec = mujoco.MjSpec()\n"
            "spec.worldbody.add_body(pos=[0, 0, 1]).add_geom(size=[0.1, 0, 0])\n"
            "print(render_robot(spec, 64, 48).std() > 5)\n")
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    if env.get("DISPLAY"):
        pytest.skip("a display is present: MuJoCo's GLFW default works anyway")
    got = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True,
                         text=True, timeout=120)
    assert got.returncode == 0, got.stderr[-2000:]
    assert got.stdout.strip() == "True"


def test_render_sizes_out_of_range(tmp_path: Path) -> None:
    """A width of 0 returned an empty image, -5 was a NumPy traceback; an image wider than the
    GL driver's framebuffers (40,000 px: more than any driver's 16,384 or 32,768) was reported
    as "off-screen rendering unavailable", as if there were no OpenGL at all."""
    from robovae.errors import SettingsError

    spec = _legged_spec()
    for w, h in ((0, 24), (-5, 24), (32, 2.5)):
        with pytest.raises(SettingsError, match=r"render_robot\.(width|height) must be an integer"):
            R.render_robot(spec, w, h)
    with pytest.raises(SettingsError, match=r"robot_camera\.settle_seconds"):
        R.robot_camera(spec, settle_seconds=-1.0)
    with pytest.raises(SettingsError, match=r"side_by_side\.height"):
        R.side_by_side(spec, spec, tmp_path / "s.png", size=(32, 0))
    assert not (tmp_path / "s.png").exists()
    with pytest.raises(RuntimeError, match=r"a 40000×8 image is larger than the OpenGL driver "
                                           r"renders off-screen"):
        R.render_robot(spec, 40_000, 8)
