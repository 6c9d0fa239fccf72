"""MJCF → robot graph (SPEC §1): structure, child order, and features read from MuJoCo."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import torch

from robovae.data.features import GEOM, JOINT, LINK, get_feature_set
from robovae.data.graph import children, from_networkx, limbs, to_networkx
from robovae.data.loading import load_robot
from robovae.data.mjcf import mjcf_to_graph, model_to_graph
from robovae.data.zoo import zoo_files

MENAGERIE_17 = ["agilex_piper/piper.xml", "agility_cassie/cassie.xml",
                "berkeley_humanoid/berkeley_humanoid.xml", "booster_t1/t1.xml",
                "boston_dynamics_spot/spot.xml", "fourier_n1/n1.xml",
                "google_barkour_v0/barkour_v0.xml", "google_barkour_vb/barkour_vb.xml",
                "pal_talos/talos.xml", "pal_tiago/tiago.xml", "pal_tiago_dual/tiago_dual.xml",
                "unitree_a1/a1.xml", "unitree_g1/g1.xml", "unitree_go1/go1.xml",
                "unitree_go2/go2.xml", "unitree_h1/h1.xml", "unitree_z1/z1.xml"]


def zoo_path(name: str):
    return dict(zoo_files()[0])[name]


def test_go2_graph(menagerie_dir):
    d = mjcf_to_graph(menagerie_dir / "unitree_go2" / "go2.xml")
    assert d.num_nodes == 26
    assert int((d.node_type == LINK).sum()) == 13 and int((d.node_type == JOINT).sum()) == 13
    assert d.x.shape == (26, 34)
    fs = get_feature_set("paper34")
    assert torch.equal(d.x_mask, fs.type_mask()[d.node_type])
    assert d.x_mask[d.node_type == LINK].sum(1).eq(22).all()
    assert d.x_mask[d.node_type == JOINT].sum(1).eq(12).all()
    assert d.node_type[0] == JOINT and d.parent[0] == -1  # the free joint is the root
    assert int(d.depth.max()) == 7  # free, base, hip j, hip, thigh j, thigh, calf j, calf
    assert limbs(d) == 4
    assert d.edge_index.shape == (2, 50)  # both directions
    assert "mesh files missing" in d.warnings


def _body_order_from_spec(path):
    spec = load_robot(path).spec
    return [b.name for b in spec.bodies[1:]]


@pytest.mark.parametrize("rel", ["unitree_go2/go2.xml", "unitree_h1/h1.xml",
                                 "boston_dynamics_spot/spot.xml"])
def test_child_order_follows_the_file(menagerie_dir, rel):
    """Link nodes in pre-order are the bodies in declaration order (MjSpec's own order)."""
    loaded = load_robot(menagerie_dir / rel)
    d = model_to_graph(loaded.model)
    links = d.mj_id[d.node_type == LINK].tolist()
    assert [loaded.model.body(b).name for b in links] == _body_order_from_spec(menagerie_dir / rel)
    # joints sit between a body and its parent body, in declaration order
    kids = children(d.parent)
    for i in torch.nonzero(d.node_type == JOINT).view(-1).tolist():
        (child,) = kids[i]
        body = child
        while d.node_type[body] == JOINT:
            (body,) = kids[body]
        assert loaded.model.jnt_bodyid[d.mj_id[i]] == d.mj_id[body]


@pytest.mark.parametrize("rel", MENAGERIE_17)
def test_all_17_menagerie_robots_load(menagerie_dir, rel):
    d = mjcf_to_graph(menagerie_dir / rel)
    assert d.num_nodes > 5 and torch.isfinite(d.x).all()


def _check_features_against(model: mujoco.MjModel, d) -> None:
    fs = get_feature_set("paper34")
    s = fs.slice
    for i in range(d.num_nodes):
        row, k = d.x[i].double().numpy(), int(d.mj_id[i])
        if d.node_type[i] == LINK:
            b = model.body(k)
            np.testing.assert_allclose(row[s("link.pos")], b.pos, rtol=1e-6, atol=1e-7)
            np.testing.assert_allclose(row[s("link.mass")], b.mass, rtol=1e-6)
            np.testing.assert_allclose(row[s("link.inertia")], b.inertia, rtol=1e-5, atol=1e-9)
            np.testing.assert_allclose(row[s("link.quat")], b.quat, atol=1e-6)
            np.testing.assert_allclose(row[s("link.subtreemass")], b.subtreemass, rtol=1e-6)
            np.testing.assert_allclose(row[s("link.ipos")], b.ipos, atol=1e-6)
            np.testing.assert_allclose(row[s("link.iquat")], b.iquat, atol=1e-6)
        else:
            j = model.joint(k)
            dof = model.jnt_dofadr[k]
            rng = j.range if model.jnt_limited[k] else np.zeros(2)
            np.testing.assert_allclose(row[s("joint.range")], rng, atol=1e-6)
            np.testing.assert_allclose(row[s("joint.axis")], j.axis, atol=1e-6)
            np.testing.assert_allclose(row[s("joint.pos")], j.pos, atol=1e-6)
            np.testing.assert_allclose(row[s("joint.stiffness")], j.stiffness, rtol=1e-6)
            np.testing.assert_allclose(row[s("joint.damping")], model.dof_damping[dof], rtol=1e-6)
            np.testing.assert_allclose(row[s("joint.armature")], model.dof_armature[dof],
                                       rtol=1e-6)
            np.testing.assert_allclose(row[s("joint.frictionloss")],
                                       model.dof_frictionloss[dof], rtol=1e-6)


@pytest.mark.parametrize("name", ["gym_ant", "dmc_humanoid", "dmc_quadruped", "gym_walker2d"])
def test_features_equal_compiled_model_zoo(name):
    """Compared with an independent ``MjModel.from_xml_path`` compile of the same file."""
    path = zoo_path(name)
    d = mjcf_to_graph(path)
    _check_features_against(mujoco.MjModel.from_xml_path(str(path)), d)


@pytest.mark.parametrize("rel", ["unitree_go2/go2.xml", "unitree_h1/h1.xml",
                                 "agility_cassie/cassie.xml"])
def test_features_equal_compiled_model_menagerie(menagerie_dir, rel):
    """Menagerie files compile only once missing meshes are dropped; the values must still be
    MuJoCo's: every node is checked against the model through its MuJoCo id."""
    loaded = load_robot(menagerie_dir / rel)
    _check_features_against(loaded.model, model_to_graph(loaded.model))


def test_size_is_first_collision_geom():
    path = zoo_path("gym_ant")
    model = mujoco.MjModel.from_xml_path(str(path))
    d = mjcf_to_graph(path)
    s = get_feature_set("paper34").slice("link.size")
    torso = int(torch.nonzero(d.node_type == LINK)[0])
    b = int(d.mj_id[torso])
    g = model.body_geomadr[b]
    np.testing.assert_allclose(d.x[torso, s].numpy(), model.geom_size[g], rtol=1e-6)


def test_props_dropped_with_warning():
    d = mjcf_to_graph(zoo_path("dmc_quadruped"))
    assert "dropped 1 other top-level bodies: 'ball'" in d.warnings


def test_full_feature_set_has_geom_nodes():
    path = zoo_path("gym_ant")
    model = mujoco.MjModel.from_xml_path(str(path))
    d = mjcf_to_graph(path, "full")
    fs = get_feature_set("full")
    robot_geoms = sum(model.body_geomnum[1:])
    assert int((d.node_type == GEOM).sum()) == robot_geoms
    geoms = d.node_type == GEOM
    assert d.x[geoms][:, fs.slice("geom.type")].sum(1).eq(1).all()
    assert d.x[d.node_type == JOINT][:, fs.slice("joint.type")].sum(1).eq(1).all()
    act = d.x[d.node_type == JOINT][:, fs.slice("joint.actuated")].sum()
    assert int(act) == model.nu  # one motor per hinge in the ant
    parents_of_geoms = d.parent[geoms]
    assert (d.node_type[parents_of_geoms] == LINK).all()


def test_urdf_goes_through_mujoco(tmp_path):
    from tests.conftest import CORPUS

    d = mjcf_to_graph(CORPUS / "good_arm.urdf")
    assert d.num_nodes == 2 and d.node_type.tolist() == [JOINT, LINK]


def test_networkx_round_trip(menagerie_dir):
    d = mjcf_to_graph(menagerie_dir / "unitree_h1" / "h1.xml")
    g = to_networkx(d)
    assert g.number_of_nodes() == d.num_nodes and g.number_of_edges() == d.num_nodes - 1
    back = from_networkx(g, "paper34")
    assert torch.equal(back.parent, d.parent) and torch.equal(back.node_type, d.node_type)
    assert torch.equal(back.x, d.x)
