"""Files written whole or not at all, and robot files found in folders.

:func:`atomic_write` puts text into a temporary file beside its destination and moves it into
place with ``os.replace``: a reader (or a run continued after a crash) sees the old file or the
new one, never half of one. Robot files, scene files, procedural robots, reports and
optimisation logs are written with it; :func:`atomic_json` writes a JSON document so.
:func:`robot_files` lists the robot files that commands given files and folders work on;
:func:`writable` and :func:`writable_file` check, before a long run, that its files can be made
where they go. :class:`FolderLock` keeps a second run from writing into a folder while a first
one does (two terminals, two jobs of a cluster array given one ``--out``).
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path

from robovae.errors import RobovaeError

try:  # POSIX advisory locks; elsewhere (Windows) folders are not guarded
    import fcntl
except ImportError:  # pragma: no cover - POSIX here
    fcntl = None  # type: ignore[assignment]

__all__ = ["LOCK", "FolderLock", "atomic_json", "atomic_write", "robot_files", "writable",
           "writable_file"]

_ATTEMPTS = 100  # temporary names tried before giving up


def atomic_write(path: str | os.PathLike, text: str | bytes | memoryview,
                 durable: bool = True) -> Path:
    """Write ``text`` (a string as UTF-8, or bytes as they are) to ``path`` atomically;
    returns ``path``.

    The temporary file is ``.<name>.<pid>.tmp`` in ``path``'s folder (``.<name>.<pid>.<k>.tmp``
    when that name is taken, e.g. by a crashed writer of the same pid), created exclusively
    with the mode an ordinary ``open`` gives (``0o666`` less the umask), fsync'ed when
    ``durable`` (callers that sync a whole batch at once, e.g. with ``os.sync``, may skip it),
    then moved onto ``path``. On any error the temporary file is removed and ``path`` is left
    as it was; an ``OSError`` of the writing (a full disk) names ``path``.
    """
    path = Path(path)
    for k in range(_ATTEMPTS):
        tmp = str(path.parent / f".{path.name}.{os.getpid()}{f'.{k}' if k else ''}.tmp")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            break
        except FileExistsError:
            if k == _ATTEMPTS - 1:
                raise
    try:
        try:
            data = memoryview(text.encode("utf-8") if isinstance(text, str) else text)
            while data:
                data = data[os.write(fd, data):]
            if durable:
                os.fsync(fd)
        except OSError as e:
            raise OSError(e.errno, e.strerror, str(path)) from None
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def atomic_json(path: str | os.PathLike, obj: object, durable: bool = True) -> Path:
    """:func:`atomic_write` of ``obj`` as JSON (indented by one space); returns ``path``."""
    return atomic_write(path, json.dumps(obj, indent=1), durable)


def robot_files(paths: Sequence[str | os.PathLike]) -> list[Path]:
    """Robot files from files and folders, in the order given: a file as it is; a folder's
    ``robot.xml`` (one robot's folder, as ``robovae generate`` and ``optimize`` write them),
    else its ``robot_*/robot.xml`` (a ``generate`` folder), else its ``*/robot.xml`` (e.g. an
    ``optimize`` run's ``best/<method>``), else its ``*.xml``; each list sorted.

    Raises:
        RobovaeError: a path that is neither a file nor a folder (one line).
    """
    found: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found += ([p / "robot.xml"] if (p / "robot.xml").is_file() else
                      sorted(p.glob("robot_*/robot.xml")) or sorted(p.glob("*/robot.xml"))
                      or sorted(p.glob("*.xml")))
        elif p.is_file():
            found.append(p)
        else:
            raise RobovaeError(f"robovae: {p}: no such file or folder")
    return found


def writable(out: str | os.PathLike, what: str = "files", make: bool = True) -> Path:
    """Create the folder ``out`` (and its parents) and check that files can be made in it;
    returns it. ``make=False``: make no folder, check the nearest of ``out`` and its parents
    that exists instead (a run refused later leaves no empty folder behind; the writer makes
    ``out``).

    Raises:
        RobovaeError: one line naming ``out`` (``cannot write <what> there``) when it cannot be
            created or written to.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RobovaeError(f"robovae: {out}: cannot write {what} there (a file, not a folder)")
    if not make:
        writable(next(p for p in (out, *out.parents) if p.exists()), what)
        return out
    try:
        out.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=out).close()
    except OSError as e:
        raise RobovaeError(f"robovae: {out}: cannot write {what} there "
                           f"({e.strerror or type(e).__name__})") from None
    return out


def writable_file(path: str | os.PathLike, what: str = "files") -> Path:
    """Check that the file ``path`` can be written, before the work that makes it: it is not a
    folder, and the nearest of its folders that exists is a folder that can be written to
    (:func:`writable`); returns it. Makes no folder: a run refused later leaves none behind
    (the writer makes ``path``'s folder).

    Raises:
        RobovaeError: one line naming ``path`` or that folder.
    """
    path = Path(path)
    if path.is_dir():
        raise RobovaeError(f"robovae: {path}: a folder, not a file name for the {what}")
    writable(path.parent, what, make=False)
    return path


#: The lock file a run holds in its output folder while it writes there (removed at its end).
LOCK = ".robovae.lock"


class FolderLock:
    """An exclusive lock on the output folder ``out`` for one run, held from :meth:`acquire`
    (or ``with``) to :meth:`release`: a second run into the same folder is refused in one line
    instead of writing every robot again beside the first (two manifests' worth of records) or
    rewriting an optimisation log under it.

    The lock is ``flock`` on ``out/.robovae.lock`` (the folder is made first, as by
    :func:`writable`): the kernel drops it when its process ends, so a run killed outright leaves
    no stale lock (only the file, which the next run takes over). The file holds the owner's
    process id, for the message; it is removed on release, and a lock taken on a file that its
    owner removed meanwhile is taken again on the new one. With ``wait`` a second holder waits
    for the first instead of being refused (a shared cache built once). With ``beside`` the
    lock file is ``.<name>.robovae.lock`` next to ``out`` and ``out`` is not made: for an
    output built elsewhere and renamed into place whole, which must stay empty or absent until
    then (``robovae interpolate``). Not re-entrant: a
    process holds a folder once. Without ``fcntl`` (Windows) the folder is not guarded, nor
    (with a warning) on a file system that has no locks.

    Raises:
        RobovaeError: (from :meth:`acquire`) another run holds the folder (without ``wait``),
            or the folder cannot be made or written to.
    """

    def __init__(self, out: str | os.PathLike, what: str = "files", wait: bool = False,
                 beside: bool = False) -> None:
        self.out, self.what, self.wait = Path(out), what, wait
        self.path = self.out.parent / f".{self.out.name}{LOCK}" if beside else self.out / LOCK
        self._fd: int | None = None

    def acquire(self) -> FolderLock:
        """Take the lock; returns ``self``. Held by another process: refused, or with ``wait``
        waited for (said once on stderr)."""
        writable(self.path.parent, self.what)
        if fcntl is None or self._fd is not None:
            return self
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                owner = os.read(fd, 32).decode(errors="replace").strip() or "unknown"
                if not self.wait:
                    os.close(fd)
                    raise RobovaeError(f"robovae: {self.out}: another run is writing there "
                                       f"(process {owner}, {self.path.name}); wait for it to "
                                       "end or use another output folder") from None
                print(f"robovae: {self.out}: waiting for process {owner}, which is writing "
                      f"{self.what} there", file=sys.stderr, flush=True)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX)
                except BaseException:  # Ctrl-C while waiting: the file is not left open
                    os.close(fd)
                    raise
            except OSError as e:  # a file system without locks (some network mounts)
                os.close(fd)
                self.path.unlink(missing_ok=True)
                warnings.warn(f"robovae: {self.out}: no file locks on this file system "
                              f"({e.strerror or type(e).__name__}): a second run into the "
                              "folder is not refused", stacklevel=2)
                return self
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()}\n".encode())
                self._fd = fd
                return self
            os.close(fd)  # its owner removed it as we opened it: lock the file there now

    def release(self) -> None:
        """Remove the lock file and drop the lock (nothing when not held)."""
        if self._fd is None:
            return
        self.path.unlink(missing_ok=True)
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
