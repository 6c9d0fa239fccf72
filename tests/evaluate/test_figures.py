"""robovae render: original vs reconstruction pictures and sample contact sheets."""

from __future__ import annotations

import numpy as np
from matplotlib import image as mpimg

from robovae.cli import main
from robovae.data.zoo import zoo_files
from robovae.evaluate.figures import reconstruction_figure
from robovae.files import robot_files
from robovae.generate.pipeline import generate


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
