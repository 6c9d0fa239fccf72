"""Bad input: one line naming the file and the problem; the good files still load."""

from __future__ import annotations

import pytest

from robovae.cli import main
from robovae.data.dataset import RobotDataset
from robovae.data.mjcf import mjcf_to_graph
from robovae.errors import RobotFileError
from tests.conftest import CORPUS

EXPECTED = {
    "bad_malformed.xml": "malformed XML",
    "bad_root_tag.xml": "Unrecognized XML model type: 'notmujoco'",
    "bad_missing_include.xml": "Error opening file 'does_not_exist.xml' (element 'include'",
    "bad_empty_worldbody.xml": "no bodies in worldbody",
    "bad_nan_size.xml": "nan size in geom (element 'g', line 1)",
    "bad_unknown_element.xml": "unrecognized element (element 'wing', line 1)",
    "bad_negative_mass.xml": "mass and inertia of moving bodies must be larger",
    "bad_joint_type.xml": "invalid keyword: 'telescope' (element 'joint', line 1)",
    "bad_attribute_value.xml": "bad format in attribute 'pos' (element 'body', line 1)",
    "bad_inf_pos.xml": "non-finite values in body_pos",
    "bad_entity_bomb.xml": "DOCTYPE/ENTITY declarations are not allowed",
    "bad_not_utf8.xml": "not UTF-8 text",
    "bad_empty_file.xml": "empty file",
    "bad_duplicate_name.xml": "repeated name 'a' in body",
    "bad_urdf_missing_link.urdf": "URDF joint parent or child missing",
    "bad_zero_size.xml": "size 0 must be positive in geom",
    "bad_missing_mesh_no_inertial.xml": "after dropping 1 mesh geoms whose files are missing",
}
GOOD = ["good_arm.urdf", "good_missing_mesh.xml", "good_pendulum.xml"]


def test_corpus_is_complete():
    files = {p.name for p in CORPUS.iterdir()}
    assert set(EXPECTED) | set(GOOD) == files
    assert len(EXPECTED) >= 15


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_bad_file_gives_one_line(name):
    path = CORPUS / name
    with pytest.raises(RobotFileError) as err:
        mjcf_to_graph(path)
    line = str(err.value)
    assert "\n" not in line
    assert line.startswith(f"robovae: {path}: ")
    assert EXPECTED[name] in line


def test_missing_file_and_wrong_suffix(tmp_path):
    with pytest.raises(RobotFileError, match="no such file"):
        mjcf_to_graph(tmp_path / "nope.xml")
    (tmp_path / "robot.txt").write_text("<mujoco/>")
    with pytest.raises(RobotFileError, match="unsupported file type"):
        mjcf_to_graph(tmp_path / "robot.txt")


def test_build_goes_on_with_good_files(cache_root):
    ds = RobotDataset(cache_root, [f"dir:{CORPUS}"], progress=False)
    assert sorted(ds.names) == ["arm", "meshy", "pendulum"]
    skipped = ds.report["skipped"]
    assert len(skipped) == len(EXPECTED)
    assert all(line.startswith("robovae: ") and "\n" not in line for line in skipped)


def test_cli_reports_skipped_without_traceback(tmp_path, capsys):
    rc = main(["data", "--root", str(tmp_path), "--source", f"dir:{CORPUS}"])
    out, err = capsys.readouterr()
    assert rc == 0
    assert "pendulum" in out and "3 robots" in out and f"{len(EXPECTED)} skipped" in out
    assert "Traceback" not in out + err
    assert len([ln for ln in err.splitlines() if ln.startswith("robovae: ")]) == len(EXPECTED)


def test_cli_unknown_source_is_one_line(tmp_path, capsys):
    assert main(["data", "--root", str(tmp_path), "--source", "bogus:x"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("robovae: unknown source 'bogus:x'") and "\n" not in err
