"""mkdocs hooks: the CLI reference page is generated from robovae's own parsers at build time."""

from __future__ import annotations

import contextlib
import io
import sys

MARKER = "<!-- robovae-cli-help -->"


def _help(argv: list[str]) -> str:
    from robovae.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
        main([*argv, "--help"])
    return out.getvalue().rstrip()


def _lightning_config() -> str:
    """``robovae fit --config configs/tiny.yaml --print_config``: every option with its value."""
    from robovae.cli import main

    out, argv = io.StringIO(), sys.argv
    sys.argv = ["robovae"]  # LightningCLI warns when it sees mkdocs' own arguments
    try:
        with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
            main(["fit", "--config", "configs/tiny.yaml", "--print_config"])
    finally:
        sys.argv = argv
    return out.getvalue().rstrip()


def on_page_markdown(markdown: str, page, config, files) -> str:
    """Replace the marker of ``cli.md`` with the help of every sub-command."""
    if MARKER not in markdown:
        return markdown
    parts = ["## robovae", "", "```text", _help([]), "```", ""]
    for cmd in ("data", "generate", "interpolate", "optimize", "render", "analyze"):
        parts += [f"## robovae {cmd}", "", "```text", _help([cmd]), "```", ""]
    parts += ["## robovae fit | validate | test | predict", "",
              "The resolved configuration of `configs/tiny.yaml` "
              "(`robovae fit --config configs/tiny.yaml --print_config`): every section and key "
              "that a YAML config or a `--section.key=value` override can set.", "",
              "```yaml", _lightning_config(), "```", ""]
    return markdown.replace(MARKER, "\n".join(parts))
