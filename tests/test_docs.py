"""The documentation: the site builds with ``mkdocs build --strict``, every public function,
class and method has a docstring, and the feature tables of ``docs/data.md`` are the registry's."""

from __future__ import annotations

import importlib
import inspect
import os
import pkgutil
import subprocess
import sys
from pathlib import Path

import robovae
from robovae.data.features import FEATURE_SETS, feature_table

REPO = Path(__file__).resolve().parents[1]


def _public_objects() -> list[tuple[str, object]]:
    """Every module of robovae, and the public functions, classes and methods it defines."""
    out = []
    for info in pkgutil.walk_packages(robovae.__path__, "robovae."):
        module = importlib.import_module(info.name)
        out.append((info.name, module))
        for name, obj in vars(module).items():
            if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
                continue
            if inspect.isfunction(obj) or inspect.isclass(obj):
                out.append((f"{info.name}.{name}", obj))
            if inspect.isclass(obj):
                for attr, member in vars(obj).items():
                    if not attr.startswith("_") and inspect.isfunction(member):
                        out.append((f"{info.name}.{name}.{attr}", member))
    return out


def test_every_public_object_has_a_docstring() -> None:
    objects = _public_objects()
    assert len(objects) > 250  # the walk really saw the package
    missing = [name for name, obj in objects if not (obj.__doc__ or "").strip()]
    assert not missing, f"public objects without a docstring: {missing}"


def test_every_module_is_on_an_api_page() -> None:
    """Each module of robovae (not the packages' one-line ``__init__``) has its ``::: module``
    on a page of docs/api, and every page names only modules that exist."""
    listed = {line.removeprefix("::: ").strip() for page in (REPO / "docs" / "api").glob("*.md")
              for line in page.read_text().splitlines() if line.startswith("::: ")}
    modules = {info.name for info in pkgutil.walk_packages(robovae.__path__, "robovae.")
               if not info.ispkg and not info.name.rsplit(".", 1)[1].startswith("_")}
    assert not modules - listed, f"modules missing from docs/api: {sorted(modules - listed)}"
    packages = {info.name for info in pkgutil.walk_packages(robovae.__path__, "robovae.")}
    assert listed <= packages, f"docs/api names no such module: {sorted(listed - packages)}"


def test_feature_tables_in_docs_are_the_registry() -> None:
    doc = (REPO / "docs" / "data.md").read_text()
    for name in FEATURE_SETS:
        assert feature_table(name) in doc, (
            f"docs/data.md: the {name} table differs from the registry; regenerate it with "
            "`python -m robovae.data.features`")


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    """The site (API pages from docstrings, the CLI reference from the parsers, the notebooks,
    results.md) builds without a single warning."""
    site = tmp_path / "site"
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=REPO, capture_output=True, text=True, timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    cli = (site / "cli" / "index.html").read_text()
    assert "usage: robovae generate" in cli and "max_epochs" in cli
    api = (site / "api" / "model" / "index.html").read_text()
    assert "RoboVAE" in api and "training_step" in api
    assert "Main job" in (site / "index.html").read_text()  # README commands included
    assert (site / "notebooks" / "quickstart" / "index.html").is_file()
