"""Figures for reports: a robot and its reconstruction side by side (the paper's Figure 4), and
contact sheets of generated robots (``robovae render``)."""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from robovae.errors import RobovaeError, check_count
from robovae.evaluate.render import contact_sheet, side_by_side
from robovae.files import robot_files, writable_file

if TYPE_CHECKING:
    from robovae.model.vae import RoboVAE


def reconstruction_figure(model: RoboVAE | str | Path, robot: str | Path,
                          out: str | Path) -> dict:
    """Encode ``robot`` (a MJCF/URDF file), decode it (z = mu), write the reconstruction as MJCF
    and save ``out`` (renders side by side) and ``<out stem>_graphs.png`` (both trees).

    Returns ``{"image", "graphs", "ra", "ra_true", "exact", "fre"}``.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    # here, not at the top: a contact sheet (sample_sheet) needs neither torch nor PyG
    from robovae.data.mjcf import mjcf_to_graph
    from robovae.evaluate.graph_drawing import draw_graph
    from robovae.evaluate.metrics import reconstruction_metrics
    from robovae.generate.writer import write_robot
    from robovae.model.checkpoint import load_model
    from robovae.model.vae import RoboVAE

    out = writable_file(out, "picture")  # before the model loads
    model = model if isinstance(model, RoboVAE) else load_model(model)
    truth = mjcf_to_graph(robot, model.feature_set.name)
    recon = model.reconstruct(truth)[0]
    res = reconstruction_metrics(truth, recon, model.normalizer)
    with tempfile.TemporaryDirectory(prefix="robovae_recon_") as tmp:
        written = write_robot(recon, Path(tmp), model.feature_set, name=f"{truth.name}_recon")
        side_by_side(robot, written.robot_path, out,
                     titles=(str(truth.name), f"reconstruction (RA {res.ra:.0%})"))
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    draw_graph(truth, ax=axes[0], title=f"{truth.name}: {truth.num_nodes} nodes")
    draw_graph(recon, ax=axes[1], title=f"reconstruction: {recon.num_nodes} nodes")
    graphs = out.with_name(out.stem + "_graphs.png")
    fig.tight_layout()
    fig.savefig(graphs, dpi=100)
    plt.close(fig)
    return {"image": out, "graphs": graphs, "ra": res.ra, "ra_true": res.ra_true,
            "exact": res.exact, "fre": res.fre}


def sample_sheet(paths: Sequence[str | Path], out: str | Path, first: int = 20,
                 columns: int = 5) -> Path:
    """A contact sheet of the first ``first`` robots found in ``paths``, ``columns`` to a
    row (both at least 1)."""
    check_count("--first", first, 1)
    check_count("--columns", columns, 1)
    files = robot_files(paths)[:first]
    if not files:
        raise RobovaeError(f"robovae: {', '.join(map(str, paths))}: no robot files")
    labels = [f.parent.name if f.name == "robot.xml" else f.stem for f in files]
    return contact_sheet(files, out, columns=columns, labels=labels)
