"""The experiment runner: a config trains through the Lightning CLI and its checkpoint loads;
the report renders tables and loss curves from result files."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import torch
import yaml

from robovae.errors import RobovaeError
from robovae.evaluate import experiment_tables
from robovae.evaluate import experiments as ex
from robovae.model.checkpoint import load_model
from robovae.model.records import from_columns
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
                       "--model.tree_latent_dim=2",
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
    hp = model.hparams  # the config's model block reached the checkpoint
    assert hp.node_latent_dim == 32 and "feature_noise" not in hp
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
    monkeypatch.setattr(experiment_tables, "DOCS", tmp_path)
    ex.report(doc, root)
    text = doc.read_text()
    assert "old" not in text and "keep" in text
    assert "| 4 robots (Go1, G1, A1, H1) -> Go2 |" in text and "100.0 ± 0.0 %" in text
    assert "| go2 | 26 |" in text and "**mean over robots**" in text
    mean = 100 * (2 + 15 * 0.5) / 17  # go1, go2 exact, the rest half
    assert f"{mean:.1f} ± 0.0 %" in text


def test_report_keeps_the_tables_it_has_no_runs_for(tmp_path, monkeypatch):
    """``report --root`` of an empty folder emptied every table of docs/results.md, and a root
    with some runs emptied the others' (until 2026-11-29)."""
    doc = tmp_path / "results.md"
    doc.write_text("<!-- auto:loo -->\nmeasured\n<!-- /auto:loo -->\n"
                   "<!-- auto:experiments -->\nold\n<!-- /auto:experiments -->\n")
    monkeypatch.setattr(experiment_tables, "DOCS", tmp_path)
    before = doc.read_text()
    with pytest.raises(RobovaeError, match="no result.json of any run; .* left as it is"):
        ex.report(doc, tmp_path / "no_runs")
    assert doc.read_text() == before
    root = tmp_path / "runs"
    (root / "0").mkdir(parents=True)
    (root / "0" / "result.json").write_text(json.dumps(_fake("menagerie4", 0, "go2", 1.0)))
    ex.report(doc, root)
    text = doc.read_text()
    assert "measured" in text and "old" not in text


def test_every_report_table_has_as_many_separators_as_columns():
    results = [_fake(e, 0, "go2", 1.0) for e in ex.EXPERIMENTS]
    results += [_fake("loo", 0, n, 1.0) for n in ex.MENAGERIE17]
    for table in (ex.experiments_table(results), ex.per_robot_table(results, "menagerie4"),
                  ex.loo_table(results)):
        head, sep, *rows = table.splitlines()
        assert head.count("|") == sep.count("|"), head
        assert all(row.count("|") == head.count("|") for row in rows), table


def test_loo_specs_hold_out_one_robot():
    specs = ex.loo_specs([0, 1], robots=["go2", "barkour v0"], root=Path("r"))
    assert len(specs) == 4
    train = json.loads(specs[2].overrides[0].split("=", 1)[1])
    assert "barkour v0" not in train and len(train) == 16
    assert specs[2].out == Path("r/loo/default/barkour_v0/seed0")


@pytest.mark.parametrize("variant", list(ex.ABLATIONS))
def test_ablation_variants_are_valid_cli_overrides(variant, capsys):
    """Every variant's overrides parse on top of the configs and say what they change."""
    from robovae.cli import main

    with pytest.raises(SystemExit) as e:
        main(["fit", "--config", str(REPO / "configs" / "loo17.yaml"),
              *ex.ABLATIONS[variant][1], "--print_config"])
    assert e.value.code == 0
    config = yaml.safe_load(capsys.readouterr().out)
    model = config["model"]
    assert model["node_latent_dim"] == 32
    data = config["data"]
    assert (data["tree_surgery"] > 0) == (variant != "no_surgery")
    assert (data["feature_noise"] > 0) == (variant != "no_augment")


def test_zeroshot_and_finetune_on_the_17(trained, tmp_path, menagerie_dir, cache_root):
    """A checkpoint trained without the 17 Menagerie robots is scored on each of them from z
    and full channel with its latent costs; one fine-tuning run starts from its weights (and
    its normaliser), trains on the 16 others and scores the 17th; the report's table reads
    both. A checkpoint trained on any of the 17 is refused for zero-shot."""
    from robovae.evaluate.pretrained import finetune_specs, zeroshot

    model, _, ckpt = trained
    r = zeroshot(ckpt, "small", menagerie_dir, tmp_path, cache_root)
    assert [t["name"] for t in r["test_z"]] == list(ex.MENAGERIE17)
    assert all({"kl_z", "kl_tree", "kl_nodes", "nodes"} <= set(t) for t in r["test_z"])
    saved = json.loads((tmp_path / "zeroshot" / "small" / "result.json").read_text())
    assert [t["n_pred"] for t in saved["test_z"]] == [t["n_pred"] for t in r["test_z"]]
    extra = [f"--data.root={cache_root}", f'--data.sources=["dir:{menagerie_dir}"]',
             "--trainer.check_val_every_n_epoch=2", "--metrics.every_n_epochs=2"]
    (spec,) = finetune_specs(ckpt, "small", [0], ["go2"], extra, epochs=2, root=tmp_path)
    result = ex.run_one(spec)
    assert sorted(result["train_names"]) == sorted(n for n in ex.MENAGERIE17 if n != "go2")
    assert result["test"][0]["name"] == "go2" and result["hparams"]["hidden_dim"] == 32
    tuned = load_model(spec.out / "checkpoints" / "last.ckpt")
    assert torch.equal(tuned.normalizer.mean, model.normalizer.mean)  # the pretrained one
    results = experiment_tables.load_results(tmp_path)
    for kind in ("zeroshot", "finetune"):
        table = experiment_tables.pretrained_table(results, kind, "small")
        assert "**mean over robots**" in table and "go2" in table
    trained_on = tmp_path / "go2.ckpt"
    data = torch.load(ckpt, weights_only=True)
    # an earlier version's plain list of records, one of them go2
    data["robovae_training_robots"] = [*from_columns(data["robovae_training_robots"]),
                                       {"name": "go2"}]
    torch.save(data, trained_on)
    with pytest.raises(ValueError, match="trained on \\['go2'\\]"):
        zeroshot(trained_on, "leaky", menagerie_dir, tmp_path, cache_root)


def test_experiments_refuse_bad_input_in_one_line(tmp_path, capsys):
    """A missing checkpoint was a traceback, an unknown variant ran the default configs under
    its name, an unknown robot trained on all 17 and tested none (until 2026-11-29)."""
    cases = [(["zeroshot", "--ckpt", str(tmp_path / "none.ckpt"), "--name", "x"],
              "none.ckpt: no such checkpoint"),
             (["run", "menagerie2", "--variant", "bogus"], "unknown ablation variant bogus"),
             (["ablation", "--only", "no_surgery,bogus"], "unknown ablation variant bogus"),
             (["loo", "--robots", "go2,bogus"], "--robots names 'bogus', not one of the 17")]
    for argv, message in cases:
        assert ex.main([*argv, "--root", str(tmp_path / "runs")] if argv[0] != "zeroshot"
                       else argv) == 2
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1 and err.startswith("robovae: ")
    assert not (tmp_path / "runs").exists()
