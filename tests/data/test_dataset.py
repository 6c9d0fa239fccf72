"""RobotDataset (cache, sources, de-duplication) and RobotDataModule (splits, normaliser)."""

from __future__ import annotations

import os
import shutil

import pytest
import torch

from robovae.data.datamodule import RobotDataModule, select_names
from robovae.data.dataset import RobotDataset
from robovae.data.graph import describe


def test_zoo_builds_offline(cache_root):
    ds = RobotDataset(cache_root, ["zoo"], progress=False)
    assert len(ds) >= 15
    assert len(set(ds.names)) == len(ds)
    for name in ["gym_ant", "dmc_humanoid", "dmc_quadruped", "dmc_dog"]:
        assert name in ds.names
    assert "duplicates gym_walker2d" in " ".join(ds.report["duplicates"])


def test_cache_is_reused_and_rebuilt_on_change(tmp_path, menagerie_dir):
    src = tmp_path / "robots"
    src.mkdir()
    shutil.copy(menagerie_dir / "unitree_go2" / "go2.xml", src / "go2.xml")
    a = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False)
    b = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False)
    assert a.processed_paths == b.processed_paths
    c = RobotDataset(tmp_path / "c", [f"dir:{src}"], feature_set="full", progress=False)
    assert c.processed_paths != a.processed_paths and c.feature_set == "full"
    os.utime(src / "go2.xml", ns=(1, 1))  # touch: the source changed
    d = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False)
    assert d.processed_paths != a.processed_paths


def test_force_reload_replaces_the_cache_file_a_reader_has_mapped(tmp_path, menagerie_dir):
    """A rebuilt cache is a new file moved into place: a dataset that has the old one
    memory-mapped keeps its data, and no temporary file is left behind."""
    src = tmp_path / "robots"
    src.mkdir()
    shutil.copy(menagerie_dir / "unitree_go2" / "go2.xml", src / "go2.xml")
    old = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False)
    path = old.processed_paths[0]
    inode, x = os.stat(path).st_ino, old[0].x.clone()
    new = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False, force_reload=True)
    assert new.processed_paths[0] == path and os.stat(path).st_ino != inode
    assert torch.equal(old[0].x, x) and torch.equal(new[0].x, x)
    assert not [f for f in os.listdir(os.path.dirname(path)) if f.endswith(".tmp")]


def test_cache_key_holds_the_reader_code(tmp_path, menagerie_dir, monkeypatch):
    """Another version of the code that reads files into graphs (features, mjcf, ...) does
    not reuse a cache: a feature column added or read differently would come back stale."""
    import robovae.data.dataset as dataset

    src = tmp_path / "robots"
    src.mkdir()
    shutil.copy(menagerie_dir / "unitree_go2" / "go2.xml", src / "go2.xml")
    a = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False)
    assert len(dataset.reader_digest()) == 12
    monkeypatch.setattr(dataset, "reader_digest", lambda: "another_code")
    b = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False)
    assert b.processed_paths != a.processed_paths


def test_scene_and_robot_file_are_one_robot(tmp_path, menagerie_dir):
    """A Menagerie-style folder: scene.xml includes the robot file; one robot, named by it."""
    src = tmp_path / "unitree_go2"
    src.mkdir()
    shutil.copy(menagerie_dir / "unitree_go2" / "go2.xml", src / "go2.xml")
    (src / "scene.xml").write_text(
        '<mujoco model="go2 scene"><include file="go2.xml"/><worldbody>'
        '<geom name="floor" size="0 0 0.05" type="plane"/></worldbody></mujoco>')
    ds = RobotDataset(tmp_path / "c", [f"dir:{src}"], progress=False)
    assert ds.names == ["go2"]
    assert len(ds.report["duplicates"]) == 1


def test_menagerie_package_with_local_root(tmp_path, menagerie_dir, monkeypatch):
    pytest.importorskip("mujoco_menagerie")
    monkeypatch.setenv("MENAGERIE_ROOT", str(menagerie_dir))
    ds = RobotDataset(tmp_path, ["menagerie:unitree_go2,unitree_a1,pal_talos"], progress=False)
    assert ds.names == ["go2", "a1", "talos"]
    assert ds.by_name("go2").num_nodes == 26


def test_menagerie_unknown_name(tmp_path, monkeypatch, menagerie_dir):
    pytest.importorskip("mujoco_menagerie")
    from robovae.errors import RobovaeError

    monkeypatch.setenv("MENAGERIE_ROOT", str(menagerie_dir))
    with pytest.raises(RobovaeError, match="unknown Menagerie robot 'nobot'"):
        RobotDataset(tmp_path, ["menagerie:nobot"], progress=False)


def test_only_bad_files_give_one_line_and_leave_no_cache_folder(tmp_path):
    """Every source file broken: one line naming the first file and its element, and the
    cache folders the build made are gone again (a good robot beside them is kept)."""
    from robovae.errors import RobovaeError

    src = tmp_path / "robots"
    src.mkdir()
    for name in ("a", "b"):
        (src / f"{name}.xml").write_text("<mujoco><worldbody><body><geom type='sphere' "
                                         "size='x'/></body></worldbody></mujoco>")
    root = tmp_path / "cache"
    with pytest.raises(RobovaeError) as e:
        RobotDataset(root, [f"dir:{src}"], progress=False, jobs=1)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"robovae: {src / 'a.xml'}: ")
    assert "element 'geom'" in msg and "2 files failed" in msg
    assert not root.exists()
    (src / "c.xml").write_text("<mujoco><worldbody><body><joint/><geom size='0.1'/>"
                               "<body pos='0 0 .2'><joint/><geom size='.1'/></body></body>"
                               "</worldbody></mujoco>")
    ds = RobotDataset(root, [f"dir:{src}"], progress=False, jobs=1)
    assert ds.names == ["c"] and len(ds.report["skipped"]) == 2


def test_a_cache_folder_that_cannot_be_made_is_one_line(tmp_path, capsys):
    """``robovae data --root`` inside a file: one line naming the folder, no traceback."""
    from robovae.cli import main

    (tmp_path / "file").write_text("keep")
    assert main(["data", "--root", str(tmp_path / "file" / "cache"), "--jobs", "1"]) == 2
    err = capsys.readouterr().err
    assert "file/cache: cannot write the dataset cache there" in err
    assert len(err.strip().splitlines()) == 1 and (tmp_path / "file").read_text() == "keep"


def test_a_full_disk_while_the_cache_is_written_is_one_line(tmp_path):
    """``robovae data`` whose cache file cannot be written (the disk full; here the file grows
    past ``RLIMIT_FSIZE``): exit status 1, one line naming the cache file, no partial cache
    left (until 2026-11-29 a traceback of ``torch.save``'s zip writer, ``RuntimeError: [enforce
    fail at inline_container.cc] unexpected pos``, which did not say the disk was full)."""
    import subprocess
    import sys

    from tests.conftest import with_file_size_limit

    root = tmp_path / "cache"
    run = subprocess.run([sys.executable, "-m", "robovae.cli", "data", "--root", str(root),
                          "--source", "procedural:n=40,seed=0", "--jobs", "1"],
                         capture_output=True, text=True, preexec_fn=with_file_size_limit(65_536))
    assert run.returncode == 1, run.stderr[-2000:]
    assert "Traceback" not in run.stderr
    last = run.stderr.splitlines()[-1]
    assert last.startswith(f"robovae: {root / 'processed'}/robots_") and last.endswith(
        ".pt: cannot write there (File too large); what was written whole is kept")
    assert not list(root.rglob("*.pt"))


def test_one_source_string_is_one_source_and_jobs_are_checked(tmp_path):
    """``RobotDataset(root, "procedural:n=3")``: one source (until 2026-11-29 each character was
    a source: ``"zoo"`` read files ``z``, ``o``, ``o``); ``jobs`` an integer >= 0."""
    ds = RobotDataset(tmp_path / "a", "procedural:n=3", progress=False)
    assert ds.sources == ["procedural:n=3"] and len(ds) == 3
    with pytest.raises(ValueError, match="RobotDataset.jobs must be an integer >= 0, got -1"):
        RobotDataset(tmp_path / "b", ["procedural:n=3"], jobs=-1)
    assert not (tmp_path / "b").exists()


def test_parallel_runs_on_one_root_build_the_cache_once(tmp_path):
    """Processes asking for one uncached dataset (training runs of an experiment sharing
    ``data_cache``): one builds it, the others wait for it and read its cache, instead of each
    building it (the CPU and the memory many times over) and replacing each other's file. Here
    both wait on a lock this test holds, then one builds."""
    import subprocess
    import sys

    from robovae.files import LOCK, FolderLock

    code = ("import sys\nimport robovae.data.dataset as d\n"
            "build = d.RobotDataset.process\n"
            "def counted(self):\n    print('BUILT', flush=True)\n    build(self)\n"
            "d.RobotDataset.process = counted\n"
            "ds = d.RobotDataset(sys.argv[1], ['procedural:n=300,seed=5'], progress=False,"
            " jobs=1)\nprint('ROBOTS', len(ds), flush=True)\n")
    processed = tmp_path / "cache" / "processed"
    with FolderLock(processed):
        runs = [subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "cache")],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                for _ in range(2)]
        for r in runs:  # each says it waits (its stderr's other lines: warnings, if any)
            assert r.stderr is not None
            while "waiting for process" not in (line := r.stderr.readline()):
                assert line, "the process ended without waiting"
            assert f"waiting for process {os.getpid()}, which is writing the dataset cache" \
                in line
    outs = [r.communicate(timeout=600) for r in runs]
    assert [r.returncode for r in runs] == [0, 0], outs
    assert sum(o.count("BUILT") for o, _ in outs) == 1, outs
    assert all("ROBOTS 300" in o for o, _ in outs)
    assert not (processed / LOCK).exists()


def test_datamodule_split_by_name_fits_normalizer_on_train(cache_root, menagerie_dir):
    dm = RobotDataModule([f"dir:{menagerie_dir}"], root=str(cache_root),
                         train_names=["go1", "a1"], test_names=["go2"], batch_size=2)
    dm.setup("fit")
    assert [d.name for d in dm.train_set] == ["go1", "a1"]
    assert [d.name for d in dm.test_set] == ["go2"]
    x = torch.cat([d.x for d in dm.train_set])
    t = torch.cat([d.node_type for d in dm.train_set])
    y = dm.normalizer(x, t)
    link_mass = dm.normalizer.feature_set.slice("link.mass").start
    assert abs(float(y[t == 0, link_mass].mean())) < 1e-5  # standardised on train only
    batch = next(iter(dm.train_dataloader()))
    assert batch.num_graphs == 2 and batch.x.shape[1] == 34
    # the rows the normaliser was fitted on are exactly the training robots' nodes (in
    # storage order), also through a subset view of the dataset
    order = sorted(dm.dataset.names.index(n) for n in ("go1", "a1"))
    xs, ts, rows = dm.dataset.node_rows(order)
    assert torch.equal(xs[rows], torch.cat([dm.dataset[i].x for i in order]))
    assert torch.equal(ts[rows], torch.cat([dm.dataset[i].node_type for i in order]))
    view = dm.dataset[order[::-1]]
    assert torch.equal(view.node_rows([0])[2], dm.dataset.node_rows([order[-1]])[2])


def test_select_names_patterns_keep_order_without_repeats():
    names = ["go1", "go2", "a1", "proc_quadruped_00000", "proc_hexapod_00001"]
    assert select_names(names, ["a1", "proc_*", "a1", "go?"]) == [2, 3, 4, 0, 1]
    assert select_names(names, ["proc_[hq]*00001"]) == [4]
    with pytest.raises(KeyError, match="'nobot'"):
        select_names(names, ["go1", "nobot"])
    with pytest.raises(KeyError, match="'tiago_\\*'"):
        select_names(names, ["tiago_*"])


def test_datamodule_split_by_fraction(cache_root):
    dm = RobotDataModule(["zoo"], root=str(cache_root), val_fraction=0.2, test_fraction=0.2)
    dm.setup()
    names = [d.name for d in dm.train_set] + [d.name for d in dm.val_set] + \
        [d.name for d in dm.test_set]
    assert sorted(names) == sorted(dm.dataset.names)
    assert len(dm.test_set) == round(0.2 * len(dm.dataset))


def test_batches_move_with_pyg(cache_root):
    """A robot batch already on the device is handed on as it is (no per-attribute walk), and
    other batches (the latent indices of ``robovae predict``) take Lightning's default."""
    import torch
    from torch_geometric.data import Batch

    dm = RobotDataModule(["zoo"], root=str(cache_root), val_fraction=0.2, test_fraction=0.2)
    dm.setup("fit")
    batch = Batch.from_data_list(list(dm.train_set)[:3])
    assert dm.transfer_batch_to_device(batch, torch.device("cpu"), 0) is batch
    moved = dm.transfer_batch_to_device({"index": torch.arange(3)}, torch.device("cpu"), 0)
    assert torch.equal(moved["index"], torch.arange(3))


def test_describe(cache_root):
    ds = RobotDataset(cache_root, ["zoo"], progress=False)
    text = describe(ds.by_name("gym_ant"), "paper34")
    assert text.startswith("gym_ant: 22 nodes (13 links, 9 joints)") and "4 limbs" in text
