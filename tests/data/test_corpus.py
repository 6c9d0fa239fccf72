"""Bad input: one line naming the file and the problem; the good files still load.

``tests/data/corpus`` holds small hand-written files (``bad_*``: must fail with the one-line
error ``robovae: <file>: <what> (<element/line>)``, ``good_*``: must load, some with a
documented warning). The large cases — 5,000 bodies, a chain 1,000 deep (MJCF and URDF), more
bodies than :data:`robovae.data.robot_file.MAX_BODIES` — and a FIFO are generated in a temporary
folder. Every load runs under a per-test timeout (``thread`` method: a hang inside MuJoCo's C
code still ends the run instead of stalling CI).
"""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import mujoco
import pytest

from robovae.cli import main
from robovae.data.dataset import RobotDataset
from robovae.data.features import JOINT, LINK
from robovae.data.mjcf import mjcf_to_graph, model_to_graph
from robovae.data.robot_file import MAX_BODIES
from robovae.errors import RobotFileError
from tests.conftest import CORPUS, in_fresh_python

pytestmark = pytest.mark.timeout(120, method="thread")

EXPECTED = {
    # XML and text
    "bad_malformed.xml": "malformed XML",
    "bad_truncated.xml": "malformed XML (XML_ERROR_PARSING_ATTRIBUTE)",
    "bad_plain_text.xml": "malformed XML",
    "bad_no_root_element.xml": "XML root element not found",
    "bad_root_tag.xml": "Unrecognized XML model type: 'notmujoco'",
    "bad_unknown_element.xml": "unrecognized element (element 'wing', line 1)",
    "bad_attribute_value.xml": "bad format in attribute 'pos' (element 'body', line 1)",
    "bad_empty_file.xml": "empty file",
    "bad_not_utf8.xml": "not UTF-8 text (line 1, byte 18)",
    "bad_not_utf8_late.xml": "not UTF-8 text (line 2,",  # past the first 4 KiB
    "bad_utf16.xml": "not UTF-8 text (UTF-16 byte-order mark) (line 1)",
    "bad_binary.xml": "not UTF-8 text",
    "bad_entity_bomb.xml": "DOCTYPE/ENTITY declarations are not allowed (line 2)",
    "bad_entity_bomb_late.xml": "DOCTYPE/ENTITY declarations are not allowed (line 3)",
    "bad_char_reference.xml": "invalid character reference '&#xD800;' (line 1)",  # in a file name
    # includes
    "bad_missing_include.xml": "Error opening file 'does_not_exist.xml' (element 'include'",
    "bad_include_self.xml": "already included (element 'include'",
    "bad_include_loop_a.xml": "already included (element 'include'",
    "bad_include_loop_b.xml": "already included (element 'include'",
    "bad_include_device.xml": "included file is not a regular file (include '/dev/zero')",
    # structure
    "bad_empty_worldbody.xml": "no bodies in worldbody (worldbody)",
    "bad_world_geoms_only.xml": "no bodies in worldbody (worldbody)",
    "bad_duplicate_name.xml": "repeated name 'a' in body",
    "bad_joint_type.xml": "invalid keyword: 'telescope' (element 'joint', line 1)",
    "bad_geom_type.xml": "invalid keyword: 'blob' (element 'geom', line 1)",
    "bad_actuator_target.xml": "unknown transmission target 'nope'",
    # numbers
    "bad_nan_size.xml": "nan size in geom (element 'g', line 1)",
    "bad_nan_mass.xml": "mass and inertia of moving bodies must be larger than mjMINVAL "
                        "(element 'torso', line 1)",
    "bad_inf_mass.xml": "non-finite values in body_mass (body 'torso')",
    "bad_negative_mass.xml": "mass and inertia of moving bodies must be larger",
    "bad_huge_mass.xml": "feature value beyond the float32 range: link.mass = 1e+300 "
                         "(body 'torso')",
    "bad_inf_pos.xml": "non-finite values in body_pos (body 'torso')",
    "bad_nan_quat.xml": "non-finite values in body_quat (body 'torso')",
    "bad_zero_quat.xml": "zero quaternion is not allowed (element 'body', line 1)",
    "bad_nan_axis.xml": "non-finite values in jnt_axis (joint 'knee')",
    "bad_nan_friction.xml": "non-finite values in geom_friction (geom 'foot')",
    "bad_zero_size.xml": "size 0 must be positive in geom",
    "bad_negative_size.xml": "size 0 must be positive in geom",
    "bad_huge_size.xml": "non-finite values in body_mass (body 'torso')",
    "bad_huge_number.xml": "number is too large in attribute 'size' (element 'geom', line 1)",
    # meshes
    "bad_missing_mesh_no_inertial.xml": "after dropping 1 mesh geoms whose files are missing",
    # resources (would hang or exhaust memory inside MuJoCo)
    "bad_hfield_huge.xml": "height field too large (more than 16777216 cells) (line 1)",
    "bad_texture_huge.xml": "builtin texture too large (more than 16777216 pixels) (line 1)",
    "bad_replicate_huge.xml": f"more than {MAX_BODIES} bodies",
    "bad_flexcomp_huge.xml": "flexcomp count too large (more than 100000 points)",
    # URDF
    "bad_urdf_missing_link.urdf": "URDF joint parent or child missing (element 'joint', line 1)",
    "bad_urdf_missing_parent.urdf": "URDF joint parent or child missing (element 'joint'",
    "bad_urdf_cycle.urdf": "URDF body not found",
    "bad_urdf_joint_type.urdf": "invalid joint type in URDF joint definition",
    "bad_urdf_malformed.urdf": "malformed XML",
}
#: good file -> (robot name, documented warning it must carry; "" = no warning)
GOOD = {
    "good_arm.urdf": ("arm", "1 bodies without geoms: size features zero"),
    "good_missing_mesh.xml": ("meshy", "1 mesh files missing: mesh geoms dropped"),
    "good_urdf_missing_mesh.urdf": ("gripper", "2 mesh files missing: mesh geoms dropped"),
    "good_pendulum.xml": ("pendulum", ""),
    "good_large_values.xml": ("giant", "feature values outside their registry range"),
}

# --- generated cases ------------------------------------------------------------------------

WIDE = 5000  # bodies
DEEP = 1000  # chain depth


def _wide_mjcf(n: int) -> str:
    kids = "".join(f'<body name="b{i}" pos="0 0 0.1"><joint axis="0 1 0"/><geom size="0.01"/>'
                   "</body>" for i in range(1, n))
    return (f'<mujoco model="wide"><worldbody><body name="b0"><freejoint/><geom size="0.1"/>'
            f"{kids}</body></worldbody></mujoco>")


def _deep_mjcf(n: int) -> str:
    return ("<mujoco><worldbody>"
            + "".join(f'<body name="b{i}" pos="0 0 -0.1"><joint axis="0 1 0"/>'
                      '<geom size="0.01"/>' for i in range(n))
            + "</body>" * n + "</worldbody></mujoco>")


def _deep_urdf(n: int) -> str:
    inertial = ('<inertial><mass value="0.1"/><inertia ixx="1e-3" iyy="1e-3" izz="1e-3" ixy="0" '
                'ixz="0" iyz="0"/></inertial>')
    links = "".join(f'<link name="l{i}">{inertial}<collision><geometry><sphere radius="0.01"/>'
                    f"</geometry></collision></link>" for i in range(n))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/>'
                     f'<child link="l{i + 1}"/><origin xyz="0 0 -0.05"/><axis xyz="0 1 0"/>'
                     f'<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
                     for i in range(n - 1))
    return f'<robot name="deep_urdf">{links}{joints}</robot>'


#: generated file -> expected error substring (bad) or None (good)
GENERATED = {
    "good_wide_5000.xml": None,
    "good_deep_1000.urdf": None,
    "bad_deep_1000.xml": "XML nested too deep (MuJoCo's XML parser stops at 500 element levels",
    "bad_too_many_bodies.xml": f"more than {MAX_BODIES} bodies",
    "bad_include_too_many.xml": "would take minutes to load them (include 'many_part.xml')",
    "many_part.xml": f"more than {MAX_BODIES} bodies",  # the included file, loaded alone
    "bad_fifo.xml": "not a regular file",
}
GENERATED_GOOD = {"good_wide_5000.xml": "wide", "good_deep_1000.urdf": "deep_urdf"}


def write_generated(folder: Path) -> dict[str, Path]:
    """Write the generated cases into ``folder``; returns name -> path."""
    folder.mkdir(parents=True, exist_ok=True)
    texts = {
        "good_wide_5000.xml": _wide_mjcf(WIDE),
        "good_deep_1000.urdf": _deep_urdf(DEEP),
        "bad_deep_1000.xml": _deep_mjcf(DEEP),
        "bad_too_many_bodies.xml": _wide_mjcf(MAX_BODIES + 1),  # refused before parsing
        "bad_include_too_many.xml": '<mujoco><include file="many_part.xml"/></mujoco>',
        "many_part.xml": ('<mujoco><worldbody><replicate count="5001" offset="0 0 1"><body>'
                          '<freejoint/><geom size="0.1"/><body pos="0 0 1"><joint/>'
                          '<geom size="0.1"/></body></body></replicate></worldbody></mujoco>'),
    }
    paths = {}
    for name, text in texts.items():
        paths[name] = folder / name
        paths[name].write_text(text)
    paths["bad_fifo.xml"] = folder / "bad_fifo.xml"
    os.mkfifo(paths["bad_fifo.xml"])  # opening it for reading would block forever
    return paths


@pytest.fixture(scope="module")
def generated(tmp_path_factory) -> dict[str, Path]:
    return write_generated(tmp_path_factory.mktemp("generated"))


def _one_line(err: RobotFileError, path: Path) -> str:
    line = str(err)
    assert "\n" not in line and "Traceback" not in line
    assert line.startswith(f"robovae: {path}: ")
    return line


# --- the corpus -----------------------------------------------------------------------------


def test_corpus_is_complete():
    files = {p.name for p in CORPUS.iterdir()}
    assert set(EXPECTED) | set(GOOD) == files
    assert len(EXPECTED) + sum(v is not None for v in GENERATED.values()) >= 30


@pytest.mark.timeout(30, method="thread")
@pytest.mark.parametrize("fs", ["paper34", "full"])
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bad_file_gives_one_line(name, fs):
    path = CORPUS / name
    with pytest.raises(RobotFileError) as err:
        mjcf_to_graph(path, fs)
    assert EXPECTED[name] in _one_line(err.value, path)


@pytest.mark.timeout(30, method="thread")
@pytest.mark.parametrize("fs", ["paper34", "full"])
@pytest.mark.parametrize("name", sorted(GOOD))
def test_good_file_loads_with_documented_warning(name, fs):
    g = mjcf_to_graph(CORPUS / name, fs)
    robot, warning = GOOD[name]
    assert g.name == robot and g.num_nodes >= 2
    assert g.x.isfinite().all()
    if warning:
        assert warning in g.warnings
    else:
        assert g.warnings == ""


def test_missing_file_wrong_suffix_and_folders(tmp_path):
    with pytest.raises(RobotFileError, match="no such file"):
        mjcf_to_graph(tmp_path / "nope.xml")
    (tmp_path / "robot.txt").write_text("<mujoco/>")
    with pytest.raises(RobotFileError, match="unsupported file type"):
        mjcf_to_graph(tmp_path / "robot.txt")
    for folder in ("folder.xml", "robots"):
        (tmp_path / folder).mkdir()
        with pytest.raises(RobotFileError, match=f"{folder}: a folder, not a robot file"):
            mjcf_to_graph(tmp_path / folder)
    (tmp_path / "blank.xml").write_text("  \n\t\n")
    with pytest.raises(RobotFileError, match="empty file"):
        mjcf_to_graph(tmp_path / "blank.xml")


def test_included_fifo_and_bad_included_file(tmp_path):
    os.mkfifo(tmp_path / "pipe.xml")
    (tmp_path / "a.xml").write_text('<mujoco><include file="pipe.xml"/></mujoco>')
    with pytest.raises(RobotFileError) as err:
        mjcf_to_graph(tmp_path / "a.xml")
    assert "included file is not a regular file (include 'pipe.xml')" in _one_line(
        err.value, tmp_path / "a.xml")
    (tmp_path / "part.xml").write_bytes(b'<mujoco><worldbody><body name="\xe9"/></worldbody>'
                                        b"</mujoco>")
    (tmp_path / "b.xml").write_text('<mujoco><include file="part.xml"/></mujoco>')
    with pytest.raises(RobotFileError) as err:
        mjcf_to_graph(tmp_path / "b.xml")
    assert "not UTF-8 text (included file 'part.xml', line 1, byte 31)" in _one_line(
        err.value, tmp_path / "b.xml")


# --- large generated cases ------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(n for n, e in GENERATED.items() if e))
def test_generated_bad_case(generated, name):
    start = time.perf_counter()
    with pytest.raises(RobotFileError) as err:
        mjcf_to_graph(generated[name])
    assert GENERATED[name] in _one_line(err.value, generated[name])
    assert time.perf_counter() - start < 10  # refused before MuJoCo does the slow part


def test_5000_bodies(generated):
    g = mjcf_to_graph(generated["good_wide_5000.xml"])
    assert g.name == "wide" and g.warnings == ""
    assert int((g.node_type == LINK).sum()) == WIDE and int((g.node_type == JOINT).sum()) == WIDE
    assert int(g.depth.max()) == 3  # free joint, root, hinge, leaf


def test_urdf_chain_1000_deep(generated):
    """URDF links are not nested in the XML: a 1,000-deep chain loads (no recursion limit)."""
    g = mjcf_to_graph(generated["good_deep_1000.urdf"])
    assert g.name == "deep_urdf"
    # MuJoCo welds the root link to the world: 999 moving links, each under its hinge
    assert int(g.depth.max()) == 2 * (DEEP - 1) - 1
    assert g.parent.tolist() == list(range(-1, g.num_nodes - 1))


def test_in_memory_chain_1000_deep():
    """Graph building is iterative: a 1,000-deep spec (no XML depth limit) becomes a graph."""
    spec = mujoco.MjSpec()
    body = spec.worldbody
    for i in range(DEEP):
        body = body.add_body(name=f"b{i}", pos=[0, 0, -0.1])
        body.add_joint(type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
        body.add_geom(size=[0.01, 0, 0])
    g = model_to_graph(spec.compile(), "full")
    assert g.num_nodes == 3 * DEEP and int(g.depth.max()) == 2 * DEEP


# --- dataset build and CLI ------------------------------------------------------------------


def test_build_goes_on_with_good_files(cache_root):
    ds = RobotDataset(cache_root, [f"dir:{CORPUS}"], progress=False)
    assert sorted(ds.names) == sorted(robot for robot, _ in GOOD.values())
    skipped = ds.report["skipped"]
    assert len(skipped) == len(EXPECTED)
    assert all(line.startswith("robovae: ") and "\n" not in line for line in skipped)
    for name, want in EXPECTED.items():
        assert any(line.startswith(f"robovae: {CORPUS / name}: ") and want in line
                   for line in skipped), name
    rows = {r["name"]: r for r in ds.report["robots"]}
    for robot, warning in GOOD.values():
        assert warning in rows[robot]["warnings"]


def test_cli_reports_skipped_without_traceback(tmp_path, capsys):
    """``robovae data`` over the corpus plus the generated cases: exit 0, good robots listed,
    every bad file one ``robovae: ...`` line on stderr."""
    folder = tmp_path / "robots"
    folder.mkdir()
    for p in CORPUS.iterdir():
        shutil.copy(p, folder / p.name)
    write_generated(folder)
    rc = main(["data", "--root", str(tmp_path / "cache"), "--source", f"dir:{folder}"])
    out, err = capsys.readouterr()
    assert rc == 0
    assert "Traceback" not in out + err
    n_good, n_bad = len(GOOD) + len(GENERATED_GOOD), len(EXPECTED) + len(GENERATED) - 2
    assert f"{n_good} robots" in out and f"{n_bad} skipped" in out
    for robot in [r for r, _ in GOOD.values()] + list(GENERATED_GOOD.values()):
        assert any(line.split()[:1] == [robot] for line in out.splitlines()), robot
    lines = [ln for ln in err.splitlines() if ln.startswith("robovae: ")]
    assert len(lines) == n_bad
    for name, want in {**EXPECTED, **{n: e for n, e in GENERATED.items() if e}}.items():
        assert any(ln.startswith(f"robovae: {folder / name}: ") and want in ln
                   for ln in lines), name


def test_cli_unknown_source_is_one_line(tmp_path, capsys):
    assert main(["data", "--root", str(tmp_path), "--source", "bogus:x"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("robovae: unknown source 'bogus:x'") and "\n" not in err


def test_a_path_with_a_colon_is_a_path(tmp_path, capsys, monkeypatch):
    """A folder named ``robots:v2`` (or ``C:\\robots``) was read as source kind ``robots``
    and refused as unknown; an existing path whose colon names no kind is a path."""
    folder = tmp_path / "robots:v2"
    folder.mkdir()
    from robovae.data.zoo import zoo_files

    shutil.copy(dict(zoo_files()[0])["gym_ant"], folder / "ant.xml")
    monkeypatch.chdir(tmp_path)
    for source in ("robots:v2", str(folder), f"dir:{folder}"):
        assert main(["data", "--root", str(tmp_path / f"cache{len(source)}"),
                     "--source", source]) == 0, source
        assert "1 robots" in capsys.readouterr().out
    assert main(["data", "--root", str(tmp_path / "c"), "--source", "robots:v3"]) == 2
    assert "unknown source 'robots:v3'" in capsys.readouterr().err  # a typo, no such path


@pytest.mark.parametrize(("source", "message"), [
    # tracebacks before 2026-11-29 (int() of the text, the tree builder's checks)
    ("synthetic:n=abc", "synthetic source: n='abc' is not an integer"),
    ("synthetic:n=2,nodes=0", "synthetic source: nodes=0 is outside [1, 10000]"),
    ("synthetic:n=2,nodes=3,unseen=1", "synthetic:n=2,nodes=3,unseen=1: every tree shape of 3 "
                                       "nodes (1) is in training: none is unseen"),
    # accepted before: an unknown key ignored, n=-2 made no robot ("no robot loaded")
    ("synthetic:n=3,depth=4", "synthetic source: unknown option 'depth'"),
    ("synthetic:n=-2", "synthetic source: n=-2 is outside [1, 1000000]"),
    ("procedural:n=abc", "procedural source: n='abc' is not an integer"),
    # random trees beside robots: tracebacks before 2026-11-29 (procedural robots read with
    # random<d> features; collating two dims), or every robot file skipped (zoo)
    ("synthetic:n=2 procedural:n=3", "source 'synthetic:n=2' makes random trees with "
                                     "random<dim> features: it cannot share a dataset with "
                                     "robots ('procedural:n=3')"),
    ("zoo synthetic:n=2", "source 'synthetic:n=2' makes random trees"),
    ("synthetic:n=2,dim=3 synthetic:n=2,dim=5", "sources 'synthetic:n=2,dim=3' and "
                                                "'synthetic:n=2,dim=5' make random trees of "
                                                "different dim"),
    ("menagerie:", "source 'menagerie:' names no robot"),
    ("dir:/no/such/folder", "/no/such/folder: no such folder"),
    # read the working folder, recursively, before 2026-11-29
    ("dir:", "source 'dir:' names no folder"),
    ("file:", "source 'file:' names no file or folder"),
])
def test_cli_bad_source_options_are_one_line(source, message, tmp_path, capsys):
    argv = [a for src in source.split() for a in ("--source", src)]
    assert main(["data", "--root", str(tmp_path / "cache"), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"robovae: {message}") and "\n" not in err, err
    assert not (tmp_path / "cache").exists()


def test_sources_checked_without_torch():
    """``robovae data`` checks its sources and feature set before it imports torch and PyG
    (a typo refused in 0.4 s, not 5 s); building procedural robots' files needs neither."""
    code = ("from robovae.data.sources import check_sources\n"
            "from robovae.data.features import get_feature_set\n"
            "import robovae.data.procedural\n"
            "check_sources(['zoo', 'procedural:n=3', 'dir:.'])\n"
            "get_feature_set('kinematic')\n"
            "try:\n"
            "    check_sources(['procedural:n=0'])\n"
            "    result = None\n"
            "except Exception as e:\n"
            "    result = str(e)\n")
    result, loaded, _ = in_fresh_python(code)
    assert result == "robovae: procedural source: n=0 is outside [1, 10000000]"
    assert loaded == []


def test_robots_with_random_features_are_refused_at_once(tmp_path, capsys):
    """``--feature-set random5`` with robot sources: every file was skipped with a
    misleading 'node types must be in [0, 1)', or a procedural batch failed on its first
    robot, until 2026-11-29."""
    assert main(["data", "--root", str(tmp_path / "c"), "--source", "procedural:n=3",
                 "--feature-set", "random5"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("robovae: feature set 'random5' holds random trees' features, which no "
                   "robot has ('procedural:n=3'): read robots with paper34, kinematic or full")
    assert not (tmp_path / "c").exists()
    with pytest.raises(KeyError, match="holds random trees' features"):
        mjcf_to_graph(CORPUS / sorted(GOOD)[0], "random5")
