"""Off-screen MuJoCo pictures of robots: one robot, a contact sheet of many, two side by side.

Rendering uses :class:`mujoco.Renderer` off-screen. MuJoCo picks its OpenGL backend from the
``MUJOCO_GL`` environment variable **when** ``mujoco`` **is first imported**; this module sets
``MUJOCO_GL=egl`` (headless EGL, e.g. Mesa) unless it is already set. To use another backend,
set ``MUJOCO_GL=osmesa`` (software) or ``MUJOCO_GL=glfw`` (a desktop with a display) before
anything imports ``mujoco``. When no GL context can be created, the render functions raise
``RuntimeError("robovae: off-screen rendering unavailable (MUJOCO_GL=...): <reason>")``.

The robot is shown in the scene of :mod:`robovae.evaluate.scene` (a floor, lights and a sky
added when the model has no floor) from the camera of :mod:`robovae.evaluate.camera` (free
camera at azimuth 135°, elevation -20°, framing the whole robot) unless a ``camera`` dict
overrides any of ``lookat``, ``distance``, ``azimuth``, ``elevation``, or names a model camera
with ``{"name": "track"}``.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import math  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from robovae.errors import RobovaeError  # noqa: E402
from robovae.evaluate.camera import mjv_camera, resolve_camera  # noqa: E402
from robovae.evaluate.scene import (  # noqa: E402
    Prepared,
    Robot,
    inject_floor,
    inject_skeleton,
    model_name,
    prepare,
    scene_option,
    settle,
)
from robovae.files import writable_file  # noqa: E402
from robovae.settings import check_settings, integer, number  # noqa: E402

__all__ = ["contact_sheet", "render_robot", "robot_camera", "save_png", "side_by_side"]

_TILE_BG = np.array([235, 235, 235], dtype=np.uint8)
#: Largest contact sheet drawn, in pixels (about 1,150 tiles of 240 x 180): beyond it the sheet
#: is refused before any robot is rendered (100,000 tiles would be a 13 GB image).
MAX_SHEET_PIXELS = 50_000_000


def _gl_backend() -> str:
    try:
        from mujoco.rendering.classic import gl_context
        return str(getattr(gl_context, "_MUJOCO_GL", os.environ.get("MUJOCO_GL", "")))
    except ImportError:
        return os.environ.get("MUJOCO_GL", "")


_BACKEND_CHECKED = False


def _match_backend() -> None:
    """Honour ``MUJOCO_GL=egl|osmesa`` even when ``mujoco`` was imported before it was set.

    MuJoCo reads ``MUJOCO_GL`` once, at import. When something imported ``mujoco`` before this
    module set the variable, MuJoCo chose its default (GLFW, which needs a display); if the
    variable now asks for a headless backend, switch MuJoCo's context class to it once.
    """
    global _BACKEND_CHECKED
    if _BACKEND_CHECKED:
        return
    _BACKEND_CHECKED = True
    wanted = os.environ.get("MUJOCO_GL", "").lower().strip()
    try:
        from mujoco.rendering.classic import gl_context
    except ImportError:  # pragma: no cover - other mujoco layouts: leave them alone
        return
    if getattr(gl_context, "_MUJOCO_GL", wanted) != "" or wanted not in ("egl", "osmesa"):
        return
    try:
        if wanted == "egl":
            from mujoco.egl import GLContext
        else:
            from mujoco.osmesa import GLContext
    except Exception:  # noqa: BLE001 - keep MuJoCo's choice; creation will report the error
        return
    gl_context.GLContext = GLContext
    gl_context._MUJOCO_GL = wanted


def _check_image(name: str, width: object, height: object, settle_seconds: object) -> None:
    """Refuse an image size below one pixel or a negative settling time (one line)."""
    check_settings(name, width=(width, integer(1)), height=(height, integer(1)),
                   settle_seconds=(settle_seconds, number(0)))


def _make_renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    _match_backend()
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as e:  # GL context creation fails in many ways (ImportError, EGL errors)
        if "framebuffer is not complete" in str(e):  # the context exists, the size does not fit
            raise RuntimeError(f"robovae: a {width}×{height} image is larger than the OpenGL "
                               f"driver renders off-screen (MUJOCO_GL={_gl_backend()}; Mesa: "
                               f"16384 px a side): {type(e).__name__}: {e}") from e
        raise RuntimeError(f"robovae: off-screen rendering unavailable (MUJOCO_GL="
                           f"{_gl_backend() or '<unset>'}): {type(e).__name__}: {e}") from e


def _render_prepared(prep: Prepared, width: int, height: int,
                     camera: dict[str, Any], skeleton: bool = True) -> np.ndarray:
    renderer = _make_renderer(prep.model, width, height)
    try:
        renderer.update_scene(prep.data, camera=mjv_camera(prep.model, camera),
                              scene_option=scene_option(prep.model))
        if prep.inject_floor:
            inject_floor(prep, renderer.scene)
        if skeleton:
            inject_skeleton(prep, renderer.scene)
        return np.ascontiguousarray(renderer.render(), dtype=np.uint8)
    finally:
        renderer.close()


def render_robot(model_or_path: Robot, width: int = 480, height: int = 360,
                 camera: dict | None = None, settle_seconds: float = 0.0, *,
                 floor: bool = True, skeleton: bool = True) -> np.ndarray:
    """Render a robot off-screen.

    Args:
        model_or_path: a robot file (``.xml``/``.urdf``; missing meshes are dropped), a
            compiled ``mujoco.MjModel`` or a ``mujoco.MjSpec`` (copied, not changed).
        width: image width in pixels.
        height: image height in pixels.
        camera: overrides of the automatic camera (keys ``lookat``, ``distance``, ``azimuth``,
            ``elevation``; the distance is re-fitted when only the angles are given), or
            ``{"name": <model camera>}``.
        settle_seconds: simulate this long (on the floor) before rendering.
        floor: add a floor scene when the model has none.
        skeleton: draw markers and bones for bodies without geoms.

    Returns:
        ``uint8`` array ``[height, width, 3]``.

    Raises:
        RobotFileError: the file cannot be loaded.
        RuntimeError: no off-screen OpenGL context (see the module docstring), or an image
            larger than the driver renders.
        SettingsError: ``width`` or ``height`` below 1, ``settle_seconds`` negative.
    """
    _check_image("render_robot", width, height, settle_seconds)
    prep = prepare(model_or_path, width, height, floor=floor)
    settle(prep, settle_seconds)
    cam = resolve_camera(prep.model, prep.data, camera, width / height)
    return _render_prepared(prep, width, height, cam, skeleton=skeleton)


def robot_camera(model_or_path: Robot, width: int = 480, height: int = 360,
                 settle_seconds: float = 0.0) -> dict[str, Any]:
    """The automatic camera :func:`render_robot` would use (e.g. to render others alike);
    settings as there."""
    _check_image("robot_camera", width, height, settle_seconds)
    prep = prepare(model_or_path, width, height)
    settle(prep, settle_seconds)
    return resolve_camera(prep.model, prep.data, None, width / height)


# ----------------------------------------------------------------------------------------------
# images and figures


def save_png(image: np.ndarray, path: str | os.PathLike) -> Path:
    """Write an ``[H, W, 3|4]`` ``uint8`` (or ``[0, 1]`` float) image as PNG; returns the path.

    Uses Pillow when installed (a matplotlib dependency), else ``matplotlib.pyplot.imsave``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = (np.clip(img, 0.0, 1.0) * 255).round().astype(np.uint8)
    try:
        from PIL import Image
    except ImportError:  # pragma: no cover - Pillow comes with matplotlib
        import matplotlib.image

        matplotlib.image.imsave(path, img)
    else:
        Image.fromarray(img).save(path, format="PNG")
    return path


def _label_of(item: Robot, index: int) -> str:
    if isinstance(item, mujoco.MjModel):
        return model_name(item) or f"robot {index}"
    if isinstance(item, mujoco.MjSpec):
        return item.modelname or f"robot {index}"
    return Path(item).stem


def _save_labelled(image: np.ndarray, path: str | os.PathLike,
                   labels: Sequence[tuple[float, float, str]], fontsize: float = 10.0,
                   dpi: int = 100) -> Path:
    """Save ``image`` at its exact pixel size with text boxes at pixel positions (x, y from the
    top-left corner)."""
    h, w = image.shape[:2]
    fig = Figure(figsize=(w / dpi, h / dpi), dpi=dpi)
    fig.figimage(image, xo=0, yo=0, origin="upper")
    for x, y, text in labels:
        if text:
            fig.text(x / w, 1.0 - y / h, text, ha="left", va="top", fontsize=fontsize,
                     family="sans-serif",
                     bbox={"boxstyle": "round,pad=0.25", "facecolor": "white", "alpha": 0.75,
                           "edgecolor": "none"})
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, format="png")
    return path


def contact_sheet(items: Sequence[Robot], path: str | os.PathLike, columns: int = 5,
                  size: tuple[int, int] = (240, 180), labels: Sequence[str] | None = None,
                  max_items: int | None = None, settle_seconds: float = 0.0) -> Path:
    """A grid PNG of robot renders with labels.

    Args:
        items: robot files, models or specs (the first ``max_items`` are drawn).
        path: output PNG; its size is ``(columns·w) × (rows·h)`` pixels for ``size = (w, h)``
            (fewer columns when there are fewer items).
        labels: one label per item; default: file stem / model name.
        settle_seconds: passed to :func:`render_robot`.

    A robot that cannot be loaded gets a grey tile labelled as failed, and a one-line warning
    naming it and the error.

    Returns:
        ``path`` as a ``Path``.

    Raises:
        RobovaeError: no robot could be drawn (the first one's error; nothing is written), the
            sheet would exceed :data:`MAX_SHEET_PIXELS`, or ``path`` cannot be written (both
            refused before any rendering); SettingsError: ``columns``, the tile size or
            ``max_items`` not integers >= 1, ``settle_seconds`` negative.
    """
    check_settings("contact_sheet", columns=(columns, integer(1)), width=(size[0], integer(1)),
                   height=(size[1], integer(1)), max_items=(max_items, integer(1).or_none()),
                   settle_seconds=(settle_seconds, number(0)))
    items = list(items)[: max_items if max_items is not None else None]
    if not items:
        raise ValueError("robovae: contact_sheet needs at least one robot")
    if len(items) * size[0] * size[1] > MAX_SHEET_PIXELS:
        raise RobovaeError(f"robovae: a contact sheet of {len(items)} robots of {size[0]}x"
                           f"{size[1]} px is over {MAX_SHEET_PIXELS:,} pixels: draw at most "
                           f"{MAX_SHEET_PIXELS // (size[0] * size[1])} (render --first); "
                           f"nothing written to {path}")
    writable_file(path, "contact sheet")
    labels = list(labels) if labels is not None else [_label_of(it, i)
                                                      for i, it in enumerate(items)]
    if len(labels) < len(items):
        raise ValueError(f"robovae: {len(labels)} labels for {len(items)} robots")
    w, h = size
    cols = min(columns, len(items))  # columns >= 1 (checked), items >= 1
    rows = math.ceil(len(items) / cols)
    sheet = np.empty((rows * h, cols * w, 3), dtype=np.uint8)
    sheet[:] = _TILE_BG
    texts, failed = [], []
    for k, item in enumerate(items):
        r, c = divmod(k, cols)
        label = labels[k]
        try:
            tile = render_robot(item, w, h, settle_seconds=settle_seconds)
        except (RobovaeError, ValueError) as e:
            failed.append(f"tile {k} ({labels[k]}) left grey: "
                          f"{str(e).removeprefix('robovae: ')}")
            tile = np.full((h, w, 3), 160, dtype=np.uint8)
            label = f"{label}\n(failed)"
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = tile
        texts.append((c * w + 4, r * h + 4, label))
    if len(failed) == len(items):
        raise RobovaeError(f"robovae: no robot drawn, nothing written to {path} ({failed[0]})")
    for message in failed:
        warnings.warn(f"robovae: contact sheet {message}", stacklevel=2)
    sheet[:, ::w] = 255  # thin separators between tiles
    sheet[::h, :] = 255
    return _save_labelled(sheet, path, texts, fontsize=max(6.0, min(10.0, h / 20)))


def side_by_side(original: Robot, reconstruction: Robot, path: str | os.PathLike,
                 titles: tuple[str, str] = ("original", "reconstruction"),
                 size: tuple[int, int] = (480, 360), settle_seconds: float = 0.0) -> Path:
    """Render two robots from the same camera (fitted to ``original``) next to each other,
    like the paper's Figure 4. Writes a ``(2w) × h`` PNG and returns its path (a path that
    cannot be written: :class:`RobovaeError` before any rendering; a size below one pixel or a
    negative ``settle_seconds``: ``SettingsError``)."""
    w, h = size
    _check_image("side_by_side", w, h, settle_seconds)
    writable_file(path, "picture")
    prep = prepare(original, w, h)
    settle(prep, settle_seconds)
    cam = resolve_camera(prep.model, prep.data, None, w / h)
    left = _render_prepared(prep, w, h, cam)
    right = render_robot(reconstruction, w, h, camera=cam, settle_seconds=settle_seconds)
    image = np.concatenate([left, right], axis=1)
    image[:, w - 1:w + 1] = 255
    return _save_labelled(image, path, [(6, 6, titles[0]), (w + 6, 6, titles[1])],
                          fontsize=max(8.0, min(14.0, h / 24)))
