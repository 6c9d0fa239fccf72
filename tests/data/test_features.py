"""The feature registry and normalisation."""

from __future__ import annotations

import pytest
import torch

from robovae.data.box_axes import axes_to_quat
from robovae.data.features import JOINT, LINK, get_feature_set
from robovae.data.normalizer import Normalizer


def test_paper34_is_appendix_e():
    fs = get_feature_set("paper34")
    assert fs.dim == 34
    widths = {f.key: f.width for f in fs.features}
    assert widths == {
        "joint.range": 2, "joint.stiffness": 1, "joint.axis": 3, "joint.pos": 3,
        "joint.armature": 1, "joint.damping": 1, "joint.frictionloss": 1,
        "link.pos": 3, "link.mass": 1, "link.inertia": 3, "link.quat": 4,
        "link.subtreemass": 1, "link.ipos": 3, "link.iquat": 4, "link.size": 3}
    mask = fs.type_mask()
    assert mask[JOINT].sum() == 12 and mask[LINK].sum() == 22
    assert not (mask[JOINT] & mask[LINK]).any()
    assert len(fs.columns) == 34 and fs.columns[0] == "joint.range[0]"


def test_full_is_a_superset():
    paper, full = get_feature_set("paper34"), get_feature_set("full")
    assert {f.key for f in paper.features} < {f.key for f in full.features}
    assert full.node_types == ("link", "joint", "geom")
    with pytest.raises(KeyError):
        get_feature_set("nope")
    assert get_feature_set("random5").dim == 5


def _random_physical(n: int, fs) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    types = torch.randint(0, fs.num_node_types, (n,), generator=g)
    x = torch.rand(n, fs.dim, generator=g) * 3.0
    return x * fs.type_mask()[types], types


@pytest.mark.parametrize("name", ["paper34", "full"])
def test_normalizer_round_trip(name):
    fs = get_feature_set(name)
    x, t = _random_physical(500, fs)
    norm = Normalizer(fs).fit(x, t)
    y = norm(x, t)
    assert torch.allclose(norm.inverse(y, t), x, atol=1e-4, rtol=1e-4)
    own = fs.type_mask()[t]
    assert (y[~own] == 0).all()
    cont = ~fs.column_transform("categorical")
    # standardised over the owning nodes: mean 0, std 1 on every non-constant column
    for c in torch.nonzero(cont).view(-1).tolist():
        col = y[own[:, c], c]
        assert abs(float(col.mean())) < 1e-4


def test_normalizer_fit_in_chunks_on_selected_rows_equals_one_pass():
    """Chunked streaming fit over a row mask = fitting on the selected rows at once."""
    fs = get_feature_set("full")
    x, t = _random_physical(1000, fs)
    rows = torch.arange(1000) % 3 != 0
    whole = Normalizer(fs).fit(x[rows], t[rows], chunk=1 << 20)
    chunked = Normalizer(fs).fit(x, t, rows=rows, chunk=37)
    for key in ("mean", "std", "low", "high"):
        assert torch.allclose(whole.state_dict()[key], chunked.state_dict()[key], atol=1e-5)
    assert not torch.allclose(Normalizer(fs).fit(x, t).mean, whole.mean)  # the mask matters


def test_normalizer_state_travels_in_state_dict():
    fs = get_feature_set("paper34")
    x, t = _random_physical(100, fs)
    a = Normalizer(fs).fit(x, t)
    b = Normalizer(fs)
    b.load_state_dict(a.state_dict())
    assert bool(b.fitted) and torch.equal(a(x, t), b(x, t))


def test_log_columns_are_the_heavy_tailed_ones():
    fs = get_feature_set("paper34")
    logs = {f.key for f in fs.features if f.transform == "log"}
    assert logs == {"joint.stiffness", "joint.armature", "joint.damping", "joint.frictionloss",
                    "link.mass", "link.inertia", "link.subtreemass", "link.size"}


def test_kinematic_link_box_bounds_the_collision_geoms():
    """``link.box_*``: the oriented box bounding a body's collision geoms, body frame. A tilted
    capsule gets a tight box along its axis (not the loose body-axis box); a sphere and an
    axis-aligned box keep the body axes; a visual-only geom does not count when a collision
    geom exists; a body without geoms has zeros."""
    import mujoco
    import numpy as np

    from robovae.data.mjcf import model_to_graph

    xml = """<mujoco><worldbody><body name="root"><freejoint/>
      <geom type="sphere" size="0.1"/>
      <body name="tilted" pos="0 0 -0.1"><joint type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 -0.4" size="0.05"/>
        <geom type="sphere" size="0.5" pos="3 0 0" contype="0" conaffinity="0"/></body>
      <body name="foot" pos="0.2 0 -0.5"><joint type="hinge"/>
        <geom type="box" size="0.1 0.05 0.02" pos="0.03 0 -0.02"/></body>
      <body name="empty" pos="0 0.3 0"><joint type="hinge"/>
        <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/></body>
    </body></worldbody></mujoco>"""
    fs = get_feature_set("kinematic")
    g = model_to_graph(mujoco.MjModel.from_xml_string(xml), fs)
    links = (g.node_type == LINK).nonzero().flatten().tolist()
    box = {k: g.x[links][:, fs.slice(f"link.box_{k}")].double().numpy()
           for k in ("pos", "axes", "half")}
    box["quat"] = np.stack([axes_to_quat(a) for a in box["axes"]])
    np.testing.assert_allclose(box["half"][0], [0.1, 0.1, 0.1], atol=1e-6)
    np.testing.assert_allclose(box["axes"][0], [1, 0, -1, 0, 0, 0], atol=1e-6)  # body axes
    # the capsule: 0.5 m long between its end centres, radius 0.05, centred at (0.15, 0, -0.2)
    np.testing.assert_allclose(box["pos"][1], [0.15, 0.0, -0.2], atol=1e-3)
    np.testing.assert_allclose(box["half"][1], [0.3, 0.05, 0.05], atol=2e-3)
    axis = np.zeros(3)
    mujoco.mju_rotVecQuat(axis, np.array([1.0, 0, 0]), box["quat"][1])
    np.testing.assert_allclose(np.abs(axis), [0.6, 0.0, 0.8], atol=1e-3)
    np.testing.assert_allclose(box["pos"][2], [0.03, 0, -0.02], atol=1e-6)
    np.testing.assert_allclose(box["half"][2], [0.1, 0.05, 0.02], atol=1e-6)
    np.testing.assert_allclose(box["quat"][2], [1, 0, 0, 0], atol=1e-6)
    assert not box["half"][3].any() and not box["pos"][3].any()
    assert "1 bodies without geoms" in g.warnings


def test_joint_strength_is_the_same_whatever_the_convention():
    """``joint.torque``: one number per joint for a motor written as gear x control range
    either way round, a force-limited servo, and an unbounded servo (kp times half its range);
    0 for a joint without an actuator."""
    import mujoco

    from robovae.data.actuators import joint_strength

    xml = """<mujoco><compiler angle="radian"/><worldbody><body><freejoint/><geom size="0.1"/>
      <body><joint name="a" range="-1 1"/><geom size="0.1"/></body>
      <body><joint name="b" range="-1 1"/><geom size="0.1"/></body>
      <body><joint name="c" range="-1 1"/><geom size="0.1"/></body>
      <body><joint name="d" range="-0.5 1.5"/><geom size="0.1"/></body>
      <body><joint name="e"/><geom size="0.1"/></body>
    </body></worldbody><actuator>
      <motor joint="a" gear="300" ctrlrange="-1 1"/>
      <motor joint="b" gear="1" ctrlrange="-300 300"/>
      <position joint="c" kp="1000" forcerange="-300 300"/>
      <position joint="d" kp="300"/>
    </actuator></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    s = joint_strength(model)
    assert s[0] == 0.0 and s[5] == 0.0  # the free joint, an unactuated hinge
    torch.testing.assert_close(torch.tensor(s[1:5]), torch.full((4,), 300.0, dtype=torch.float64))
