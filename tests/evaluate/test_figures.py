"""robovae render: original vs reconstruction pictures and sample contact sheets."""

from __future__ import annotations

import numpy as np
from matplotlib import image as mpimg

from robovae.cli import main
from robovae.data.zoo import zoo_files
from robovae.evaluate.figures import reconstruction_figure
from robovae.files import robot_files
from robovae.generate.pipeline import generate
from tests.conftest import in_fresh_python


def test_reconstruction_figure(trained, tmp_path):
    model, _, _ = trained
    hopper = dict(zoo_files()[0])["gym_hopper"]
    res = reconstruction_figure(model, hopper, tmp_path / "hopper.png")
    img = mpimg.imread(res["image"])
    assert img.shape[1] == 2 * img.shape[0] * 480 // 360  # two 480x360 renders side by side
    assert np.std(img[:, : img.shape[1] // 2]) > 0.01  # not blank
    assert res["graphs"].is_file() and 0.0 <= res["ra"] <= 1.0


def test_cli_render_contact_sheet_of_samples(trained, tmp_path, capsys):
    _, _, ckpt = trained
    generate(ckpt, 4, tmp_path / "gen", validate=False, progress=False)
    assert [p.parent.name for p in robot_files([tmp_path / "gen"])] == [
        f"robot_{i:06d}" for i in range(4)]
    out = tmp_path / "sheet.png"
    assert main(["render", str(tmp_path / "gen"), "--out", str(out), "--columns", "2"]) == 0
    assert mpimg.imread(out).shape[:2] == (2 * 180, 2 * 240)
    assert main(["render", str(tmp_path / "nope"), "--out", str(out)]) == 2
    assert "no such file" in capsys.readouterr().err


def test_cli_render_refuses_an_unwritable_out_in_one_line_before_rendering(trained, tmp_path,
                                                                            capsys):
    """A folder given as --out, or one inside a file: one line each, nothing rendered."""
    _, _, ckpt = trained
    hopper = str(dict(zoo_files()[0])["gym_hopper"])
    (tmp_path / "file").write_text("")
    (tmp_path / "folder").mkdir()
    cases = [([hopper, "--out", str(tmp_path / "folder")], "folder: a folder, not a file name"),
             ([hopper, "--out", str(tmp_path / "file" / "s.png")],
              "file: cannot write contact sheet there"),
             ([hopper, "--ckpt", str(ckpt), "--out", str(tmp_path / "file" / "r.png")],
              "file: cannot write picture there")]
    for argv, message in cases:
        assert main(["render", *argv]) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "folder"]
    assert not any((tmp_path / "folder").iterdir())
    (tmp_path / "broken.xml").write_text("<mujoco><worldbody><body></mujoco>")
    assert main(["render", str(tmp_path / "broken.xml"), "--out",
                 str(tmp_path / "new" / "s.png")]) == 2  # no robot drawn
    assert "no robot drawn" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()  # checked, not made


def test_a_contact_sheet_needs_neither_torch_nor_pyg(tmp_path):
    """``robovae render`` without ``--ckpt`` imports no model code: a refusal comes in under a
    second, a sheet without the 5 s of torch and PyG imports."""
    hopper = str(dict(zoo_files()[0])["gym_hopper"])
    _, loaded, _ = in_fresh_python("from robovae.evaluate.figures import sample_sheet\n"
                                   f"result = str(sample_sheet([{hopper!r}], "
                                   f"{str(tmp_path / 's.png')!r}))")
    assert loaded == []
    assert mpimg.imread(tmp_path / "s.png").shape[:2] == (180, 240)
