"""The experiment runner: a config trains through the Lightning CLI and its checkpoint loads;
the report renders tables and loss curves from result files."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest
import yaml

from robovae.evaluate import experiments as ex
from robovae.model.checkpoint import load_model
from tests.conftest import REPO


@pytest.mark.parametrize("name", ["menagerie2", "menagerie4", "menagerie17", "loo17"])
def test_menagerie_configs_name_real_robots(name, menagerie_dir, cache_root):
    from robovae.data.dataset import RobotDataset

    cfg = yaml.safe_load((REPO / "configs" / f"{name}.yaml").read_text())
    names = set(RobotDataset(cache_root, [f"dir:{menagerie_dir}"], progress=False).names)
    data = cfg["data"]
    for key in ("train_names", "val_names", "test_names"):
        assert set(data[key]) <= names, key
    assert "go2" in data["test_names"]
    if name != "menagerie17":
        assert "go2" not in data["train_names"]
    else:
        assert set(data["train_names"]) == set(ex.MENAGERIE17) == names
    if name == "loo17":  # the runner's hold-out of Go2 is this config's own split
        assert set(data["train_names"]) | {"go2"} == set(ex.MENAGERIE17)


def test_menagerie2_trains_scores_and_loads(tmp_path, menagerie_dir, cache_root):
    spec = ex.RunSpec("menagerie2", str(REPO / "configs" / "menagerie2.yaml"), 0,
                      tmp_path / "menagerie2" / "default" / "seed0",
                      [f"--data.root={cache_root}", f'--data.sources=["dir:{menagerie_dir}"]',
                       "--model.hidden_dim=16", "--model.latent_dim=4",
                       "--trainer.check_val_every_n_epoch=3", "--metrics.every_n_epochs=3"],
                      epochs=3)
    result = ex.run_one(spec)
    saved = json.loads((spec.out / "result.json").read_text())
    assert saved["test"][0]["n_pred"] == result["test"][0]["n_pred"]
    assert result["epochs"] == 3 and result["fit_s"] > 0
    assert sorted(result["train_names"]) == ["a1", "go1"]
    (go2,) = result["test"]
    assert go2["name"] == "go2" and go2["n_true"] == 26
    header = next(csv.reader((spec.out / "metrics.csv").open()))
    assert "train/loss" in header and "val/RA" in header
    model = load_model(spec.out / "checkpoints" / "last.ckpt")
    assert model.hparams.feature_shift == 0.5
    ex.loss_curve_png(spec.out / "metrics.csv", tmp_path / "curve.png", "smoke")
    assert (tmp_path / "curve.png").stat().st_size > 1000


def _fake(exp: str, seed: int, name: str, ra: float, variant: str = "default") -> dict:
    t = {"name": name, "ra": ra, "ra_true": ra, "exact": ra == 1.0, "fre": 0.01, "n_true": 26,
         "n_pred": 26, "n_correct": int(26 * ra)}
    return {"experiment": exp, "variant": variant, "seed": seed, "epochs": 99, "fit_s": 1.0,
            "load_fit_start": 0.5, "test": [t],
            "summary": {"ra": ra, "ra_true": ra, "exact": float(ra == 1.0), "fre": 0.01,
                        "count": 1}, "metrics_csv": "missing.csv"}


def test_report_fills_the_marked_blocks(tmp_path, monkeypatch):
    root = tmp_path / "runs"
    results = [_fake("menagerie4", s, "go2", 1.0) for s in range(3)]
    results += [_fake("loo", s, n, 1.0 if n.startswith("go") else 0.5)
                for s in range(2) for n in ex.MENAGERIE17]
    for i, r in enumerate(results):
        (root / str(i)).mkdir(parents=True)
        (root / str(i) / "result.json").write_text(json.dumps(r))
    doc = tmp_path / "results.md"
    doc.write_text("# x\n<!-- auto:experiments -->\nold\n<!-- /auto:experiments -->\nkeep\n"
                   "<!-- auto:loo -->\n<!-- /auto:loo -->\n")
    monkeypatch.setattr(ex, "DOCS", tmp_path)
    ex.report(doc, root)
    text = doc.read_text()
    assert "old" not in text and "keep" in text
    assert "| 4 robots (Go1, G1, A1, H1) -> Go2 |" in text and "100.0 ± 0.0 %" in text
    assert "| go2 | 26 |" in text and "**mean over robots**" in text
    mean = 100 * (2 + 15 * 0.5) / 17  # go1, go2 exact, the rest half
    assert f"{mean:.1f} ± 0.0 %" in text


def test_loo_compare_table_puts_variants_side_by_side(tmp_path):
    results = [_fake("loo", s, n, 0.5) for s in (0, 1) for n in ex.MENAGERIE17]
    results += [_fake("loo", s, n, 1.0 - 0.5 * s, variant="surgery")
                for s in (0, 1) for n in ("go2", "z1")]
    results += [_fake("loo", 0, "h1", 1.0, variant="surgery")]  # seed 1 missing: not shown
    for i, r in enumerate(results):  # the held-out robot's val/topo, last logged value counts
        if r["variant"] == "surgery" or r["test"][0]["name"] in ("go2", "z1"):
            log = tmp_path / f"{i}.csv"
            top = 10.0 if r["variant"] == "default" else 2.0 + r["seed"]
            log.write_text(f"epoch,train/topo,val/topo\n9,1.0,\n9,,99.0\n19,,{top}\n")
            r["metrics_csv"] = str(log)
    table = ex.loo_compare_table(results)
    assert "| RA default | RA surgery | RA_true default | RA_true surgery | " \
           "topology loss default | topology loss surgery |" in table
    assert "| go2 | 26 | 50.0 ± 0.0 % | 75.0 ± 35.4 % | 50.0 ± 0.0 % | 75.0 ± 35.4 % | " \
           "10.0 ± 0.0 | 2.5 ± 0.7 | 26,26 / 26,26 |" in table
    assert "| h1 |" not in table and "| piper_description |" not in table
    assert "| **mean over 2 robots** | | 50.0 ± 0.0 % | 75.0 ± 35.4 % |" in table
    assert ex.last_logged(log, "val/topo") == 2.0  # (the last log: h1, surgery, seed 0)
    assert math.isnan(ex.last_logged(tmp_path / "nope.csv", "val/topo"))
    assert math.isnan(ex.last_logged(log, "val/RA"))
    assert "seeds 0,1" in table
    assert "| RA default |" in ex.loo_compare_table(results, ("default", "nope"))
    assert ex.loo_compare_table([], ("default",)).count("\n") == 1  # header only


def test_loo_specs_hold_out_one_robot():
    specs = ex.loo_specs([0, 1], robots=["go2", "barkour v0"], root=Path("r"))
    assert len(specs) == 4
    train = json.loads(specs[2].overrides[0].split("=", 1)[1])
    assert "barkour v0" not in train and len(train) == 16
    assert specs[2].out == Path("r/loo/default/barkour_v0/seed0")


def test_procedural_variant_adds_procedural_robots_to_the_training_split(tmp_path, menagerie_dir,
                                                                      cache_root):
    """``surgery_procedural``: its ``--data.train_names+=proc_*`` appends to the names the
    leave-one-out runner sets, so the held-out robot stays out and the procedural robots go in
    (here 3 of them instead of the variant's 100, to stay fast)."""
    (spec,) = ex.loo_specs([0], robots=["z1"], variant="surgery_procedural",
                           extra=[*ex.ABLATIONS["surgery_procedural"][1],
                                  f"--data.root={tmp_path / 'cache'}",
                                  f'--data.sources=["dir:{menagerie_dir}",'
                                  '"procedural:n=3,seed=0"]',
                                  "--model.hidden_dim=16", "--model.latent_dim=4"],
                           epochs=1, root=tmp_path)
    result = ex.run_one(spec)
    train = result["train_names"]
    assert len(train) == 19 and "z1" not in train
    assert sorted(n for n in train if n.startswith("proc_")) == \
        ["proc_hexapod_00001", "proc_humanoid_00002", "proc_quadruped_00000"]
    assert result["test"][0]["name"] == "z1" and result["hparams"]["tree_surgery"] == 0.5


def test_study_table_reads_each_runs_resolved_config(tmp_path):
    """The study rows show the settings a run was trained with (its config.yaml), not the
    current config file."""
    results = []
    for variant, inputs, lr, batch, fre in (("study-features_aug_lr3_b17", "features", 0.003,
                                             17, 0.03), ("default", "types", 0.006, 6, 5e-4)):
        run = tmp_path / variant / "seed0"
        run.mkdir(parents=True)
        (run / "config.yaml").write_text(yaml.safe_dump({
            "model": {"decoder_inputs": inputs, "lr": lr, "beta": 1e-4,
                      "feature_shift": 0.5 if inputs == "features" else 0.0,
                      "feature_noise": 0.1 if inputs == "features" else 0.0},
            "data": {"batch_size": batch},
            "trainer": {"gradient_clip_val": 10.0 if inputs == "types" else None}}))
        r = _fake("menagerie17", 0, "go2", 1.0)
        r.update(variant=variant, metrics_csv=str(run / "metrics.csv"), epochs=1500)
        r["test"][0]["fre"] = r["summary"]["fre"] = fre
        results.append(r)
    text = ex.study_table(results)
    rows = {line.split(" | ")[0]: line for line in text.splitlines()[2:]}
    assert set(rows) == {"| features_aug_lr3_b17", "| **menagerie17.yaml**"}
    assert "| features | shift 0.5, noise 0.1 | 0.003 | 17 | no |" in rows["| features_aug_lr3_b17"]
    assert "| types | no | 0.006 | 6 | 10.0 |" in rows["| **menagerie17.yaml**"]
    assert "| 0.0005 | 0.0005 | 0.0005 |" in rows["| **menagerie17.yaml**"]
    assert list(rows)[-1] == "| **menagerie17.yaml**"  # the config comes last
