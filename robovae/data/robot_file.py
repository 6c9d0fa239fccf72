"""Checking a robot file before MuJoCo parses it: size, encoding, declarations, body count.

MuJoCo's parser and compiler are super-linear in the model size and allocate some arrays in
full, so a hostile or broken file could hang a build or exhaust memory. :func:`scan_robot_file`
reads the file and the files it includes (bytes, not XML) and refuses, with a one-line
:class:`~robovae.errors.RobotFileError`, files that are not regular UTF-8 files of at most
64 MiB in all, that hold ``<!DOCTYPE``/``<!ENTITY`` declarations (no entity-expansion bombs) or
character references to characters XML forbids (``&#xD800;``, which MuJoCo would decode into
invalid UTF-8), or that declare more than :data:`MAX_BODIES` bodies (``<replicate>`` counts
multiplied in), :data:`MAX_FLEX_POINTS` ``<flexcomp>`` points, a height field larger than
:data:`MAX_HFIELD_CELLS` cells or a builtin texture larger than :data:`MAX_TEXTURE_PIXELS`
pixels. Bodies nest at most about 496 deep in MJCF (MuJoCo's XML parser stops at
:data:`XML_MAX_DEPTH` element levels).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from robovae.errors import RobotFileError

#: File suffixes of robot files (MJCF and URDF; MuJoCo reads both).
SUFFIXES = (".xml", ".mjcf", ".urdf")
_MAX_BYTES = 64 * 2**20
#: Most bodies (MJCF ``<body>``, URDF ``<link>``) a robot file and its includes may declare.
#: MuJoCo's parser and compiler are super-linear: 5,000 bodies load in ~5 s, 20,000 in ~2 min.
MAX_BODIES = 10_000
#: Most points the ``<flexcomp>`` elements of a file may generate.
MAX_FLEX_POINTS = 100_000
#: Largest height field (rows × columns) MuJoCo is asked to allocate.
MAX_HFIELD_CELLS = 2**24
#: Largest builtin texture (pixels, all cube faces) MuJoCo is asked to generate.
MAX_TEXTURE_PIXELS = 2**24
#: Element nesting MuJoCo's XML parser (tinyxml2) accepts.
XML_MAX_DEPTH = 500


_COMMENT = re.compile(rb"<!--.*?(?:-->|\Z)", re.S)
_CHAR_REF = re.compile(rb"&#(x[0-9a-fA-F]+|[0-9]+);")
_TAG = re.compile(rb"<(/?)(body|link|replicate|flexcomp|include|hfield|texture)\b([^>]*)>")
_ATTR = re.compile(rb"""\b(count|file|nrow|ncol|width|height|builtin|type)\s*=\s*"""
                   rb"""(?:"([^"]*)"|'([^']*)')""")


def _ints(text: bytes) -> list[int]:
    """The numbers of a ``count`` attribute (unparsable ones are left to MuJoCo)."""
    out = []
    for tok in text.split():
        try:
            out.append(max(0, int(float(tok))))
        except (ValueError, OverflowError):
            out.append(0)
    return out


def _line(data: bytes, offset: int) -> int:
    return data.count(b"\n", 0, offset) + 1


def _xml_char(code: int) -> bool:
    """Whether ``code`` is a character XML 1.0 allows (no NUL, controls or surrogates)."""
    return code in (0x9, 0xA, 0xD) or 0x20 <= code <= 0xD7FF or 0xE000 <= code <= 0xFFFD \
        or 0x10000 <= code <= 0x10FFFF


def scan_robot_file(path: str | Path) -> None:
    """Check a robot file and the files it includes before MuJoCo parses them.

    Raises:
        RobotFileError: unsupported suffix, missing or unreadable file, empty, too large, not
            UTF-8, DOCTYPE/ENTITY declarations, character references to forbidden
            characters, more than :data:`MAX_BODIES` bodies or :data:`MAX_FLEX_POINTS` flex
            points, height fields or builtin textures over :data:`MAX_HFIELD_CELLS` /
            :data:`MAX_TEXTURE_PIXELS`, an include that is not a regular file.
    """
    path = Path(path)
    if path.is_dir():
        raise RobotFileError(path, "a folder, not a robot file (want .xml or .urdf)")
    if path.suffix.lower() not in SUFFIXES:
        raise RobotFileError(path, f"unsupported file type '{path.suffix}' (want .xml or .urdf)")
    if not path.exists():
        raise RobotFileError(path, "no such file")
    if not path.is_file():
        raise RobotFileError(path, "not a regular file")
    base = path.parent
    seen: set[Path] = set()
    total = {"bytes": 0, "bodies": 0, "flex": 0}

    def scan(file: Path, factor: int, where: str) -> None:
        inc = f"included file '{file.name}', " if where else ""
        try:
            size = file.stat().st_size
            if total["bytes"] + size > _MAX_BYTES:
                raise RobotFileError(path, f"file too large ({(total['bytes'] + size) / 2**20:.0f}"
                                     f" MiB > {_MAX_BYTES // 2**20} MiB)", where or None)
            data = file.read_bytes()
        except OSError as e:
            raise RobotFileError(path, f"cannot read: {e.strerror or e}", where or None) from None
        total["bytes"] += len(data)
        if not data.strip():
            raise RobotFileError(path, "empty file", where or None)
        if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
            raise RobotFileError(path, "not UTF-8 text (UTF-16 byte-order mark)",
                                 f"{inc}line 1")
        try:
            data.decode("utf-8")
        except UnicodeDecodeError as e:
            raise RobotFileError(path, "not UTF-8 text",
                                 f"{inc}line {_line(data, e.start)}, byte {e.start}") from None
        for token in (b"<!DOCTYPE", b"<!ENTITY"):
            at = data.find(token)
            if at >= 0:
                raise RobotFileError(path, "DOCTYPE/ENTITY declarations are not allowed",
                                     f"{inc}line {_line(data, at)}")
        for m in _CHAR_REF.finditer(data):  # MuJoCo would turn these into invalid UTF-8
            ref = m.group(1)
            code = int(ref[1:], 16) if ref[:1] == b"x" else int(ref)
            if not _xml_char(code):
                raise RobotFileError(path, f"invalid character reference "
                                     f"'{m.group(0).decode()}'", f"{inc}line "
                                     f"{_line(data, m.start())}")
        stack = [factor]  # copies of the current element (product of enclosing replicates)
        for m in _TAG.finditer(_COMMENT.sub(b"", data)):
            closing, tag, attrs = m.group(1), m.group(2), m.group(3)
            self_closing = attrs.rstrip().endswith(b"/")
            values = {a.group(1): a.group(2) if a.group(2) is not None else a.group(3)
                      for a in _ATTR.finditer(attrs)}
            if tag == b"replicate":
                if closing:
                    if len(stack) > 1:
                        stack.pop()
                elif not self_closing:
                    n = _ints(values.get(b"count", b"1"))
                    stack.append(stack[-1] * (n[0] if n else 1))
            elif closing:
                continue
            elif tag in (b"body", b"link"):
                total["bodies"] += stack[-1]
                if total["bodies"] > MAX_BODIES:
                    raise RobotFileError(path, f"more than {MAX_BODIES} bodies: MuJoCo "
                                         "would take minutes to load them", where or None)
            elif tag == b"flexcomp":
                points = stack[-1] * math.prod(_ints(values.get(b"count", b"1")) or [1])
                total["flex"] += points
                if total["flex"] > MAX_FLEX_POINTS:
                    raise RobotFileError(path, f"flexcomp count too large (more than "
                                         f"{MAX_FLEX_POINTS} points)", where or None)
            elif tag == b"hfield":
                cells = math.prod(_ints(values.get(b"nrow", b"0") + b" "
                                        + values.get(b"ncol", b"0")))
                if cells > MAX_HFIELD_CELLS:
                    raise RobotFileError(path, f"height field too large (more than "
                                         f"{MAX_HFIELD_CELLS} cells)", f"{inc}line "
                                         f"{_line(data, m.start())}")
            elif tag == b"texture" and values.get(b"builtin", b"none").strip() != b"none":
                cube = values.get(b"type", b"").strip() in (b"cube", b"skybox")
                pixels = math.prod(_ints(values.get(b"width", b"0") + b" "
                                         + values.get(b"height", b"0"))) * (6 if cube else 1)
                if pixels > MAX_TEXTURE_PIXELS:
                    raise RobotFileError(path, f"builtin texture too large (more than "
                                         f"{MAX_TEXTURE_PIXELS} pixels)", f"{inc}line "
                                         f"{_line(data, m.start())}")
            elif tag == b"include" and b"file" in values:
                name = values[b"file"].decode("utf-8", "replace")
                target = Path(name) if Path(name).is_absolute() else base / name
                try:
                    key = target.resolve()
                except (OSError, RuntimeError):
                    continue  # MuJoCo reports it
                if key in seen or not target.exists():
                    continue  # loops and missing files: MuJoCo reports them
                if not target.is_file():
                    raise RobotFileError(path, "included file is not a regular file",
                                         f"include '{name}'")
                seen.add(key)
                scan(target, stack[-1], f"include '{name}'")

    seen.add(path.resolve())
    scan(path, 1, "")


__all__ = ["MAX_BODIES", "MAX_FLEX_POINTS", "MAX_HFIELD_CELLS", "MAX_TEXTURE_PIXELS", "SUFFIXES",
           "XML_MAX_DEPTH", "scan_robot_file"]
