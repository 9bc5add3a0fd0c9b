"""Files avq writes: whole files atomically, per-episode CSV rows by appending complete lines; and the
YAML files of a user's that it reads (:func:`read_yaml`).

A write that fails raises :class:`WriteError`, which names the path the caller
gave (never a temporary file), the cause and what to do; :func:`hold_directory`
keeps two avq processes out of one output directory.
"""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

__all__ = [
    "atomic_write_bytes",
    "make_dirs",
    "hold_directory",
    "check_output_dir",
    "file_name_part",
    "ProgressLog",
    "WriteError",
    "read_yaml",
]

#: Names Windows refuses for a file, whatever its extension.
_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)), *(f"LPT{i}" for i in range(1, 10))}


def file_name_part(text: str) -> str:
    """``text`` as part of a file or directory name valid on every system: each character but letters, digits,
    ``-``, ``_`` and ``.`` becomes ``-`` (``/`` and ``:`` of an environment id, Windows' ``<>"\\|?*``), with
    no trailing dot and not a name Windows reserves (``"user/Nav3D-v0"`` -> ``"user-Nav3D-v0"``)."""
    name = "".join(c if (c.isascii() and c.isalnum()) or c in "-_." else "-" for c in text).rstrip(".") or "-"
    return f"{name}_" if name.split(".")[0].upper() in _RESERVED else name


def read_yaml(path: str | os.PathLike, what: str) -> Any:
    """The content of a user's YAML file (None for an empty one).

    A ``ValueError`` names the file as ``what`` (``"config run.yml"``) when it cannot be read or is not
    valid YAML, with the parser's message (which gives the line and column) on one line.
    """
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            return yaml.safe_load(f)  # from the stream, so that YAML errors name the file
    except OSError as exc:
        raise ValueError(f"cannot read {what}: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{what} is not valid YAML: {' '.join(str(exc).split())}") from None


def check_output_dir(out: Path, command: str, why: str = "") -> None:
    """The rule of every output directory avq writes (``avq train``'s, ``avq sweep``'s, ``avq reproduce``'s):
    it is new, empty (but for hidden files), or the caller has recognised it as its own before calling;
    a directory holding other files is refused (a ``ValueError`` naming it, some of its files and the fix),
    so that nothing of the user's is mixed with avq's files or lost. ``why`` says what the command does to
    its directory, where that matters."""
    if not out.is_dir():
        return
    others = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if others:
        raise ValueError(
            f"--out {out} holds files that {command} did not write ({', '.join(others[:3])}"
            f"{', ...' if len(others) > 3 else ''}){why}; give a new or empty directory"
        )


class WriteError(OSError):
    """A file or directory could not be written: the message names the path, the cause and a fix.

    An ``OSError`` with the ``errno`` and ``strerror`` of the failure; its ``filename``
    is the path the caller gave.
    """

    def __init__(self, path: str | os.PathLike, cause: OSError) -> None:
        super().__init__(cause.errno, cause.strerror, str(path))
        self.message = f"cannot write {path}: {_why(Path(path), cause)}"

    def __str__(self) -> str:
        return self.message


def _why(path: Path, cause: OSError) -> str:
    """The cause of a failed write in words, with what to do about it."""
    above = [p for p in (path, *path.parents) if os.path.exists(p)]  # (os.path: False on any error)
    where = next((p for p in above if os.path.isdir(p)), Path("."))  # the deepest existing directory
    blocker = next((p for p in above if not os.path.isdir(p)), None)
    if cause.errno in (errno.ENOTDIR, errno.EEXIST) and blocker is not None:  # a file where a directory must be
        return f"{blocker} is a file, not a directory; choose a path that is not under a file"
    if cause.errno in (errno.EACCES, errno.EPERM):
        return f"no permission to write in {where}; choose a directory you can write to, or change its permissions"
    if cause.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)):
        return f"no space left on the device (or over the disk quota) of {where}; free some space"
    if cause.errno == errno.EROFS:
        return f"{where} is on a read-only file system; choose another location"
    if cause.errno == errno.EISDIR:
        return f"{path} is a directory; give a file name"
    return f"{cause.strerror or cause}"


@contextmanager
def _writing(path: str | os.PathLike) -> Iterator[None]:
    """Turn an ``OSError`` of the block into a :class:`WriteError` naming ``path``."""
    try:
        yield
    except WriteError:
        raise
    except OSError as exc:
        raise WriteError(path, exc) from exc


def make_dirs(path: str | os.PathLike) -> Path:
    """Create directory ``path`` and its parents if missing (a :class:`WriteError` if impossible)."""
    path = Path(path)
    with _writing(path):
        path.mkdir(parents=True, exist_ok=True)
    return path


@contextmanager
def hold_directory(directory: str | os.PathLike, lock_file: str | os.PathLike | None = None) -> Iterator[None]:
    """Hold ``directory`` for this process while the block runs; refuse if another process holds it.

    The hold is a lock on ``lock_file`` (default ``directory/.avq.lock``, which
    stays) taken with ``filelock``: the operating system releases it when the
    process ends, however it ends, so a killed run never leaves a directory
    stuck. The file records the holder's pid, which the refusal names.

    Raises:
        ValueError: another process holds the directory.
        WriteError: the lock file cannot be created.
    """
    from filelock import FileLock, Timeout

    directory = Path(directory)
    lock_file = Path(lock_file) if lock_file is not None else directory / ".avq.lock"
    lock = FileLock(lock_file, timeout=0)
    try:
        lock.acquire()
    except Timeout:  # (an OSError too: caught first)
        try:
            pid = lock_file.read_text(encoding="ascii").strip()
        except (OSError, UnicodeDecodeError):
            pid = ""
        holder = f" (pid {pid})" if pid.isdigit() else ""
        raise ValueError(
            f"{directory} is in use by another avq process{holder}; wait until it ends, or choose another --out"
        ) from None
    except OSError as exc:
        raise WriteError(lock_file.parent, exc) from exc  # (the directory, not the hidden file)
    try:
        # the pid is for messages only (and Windows refuses writes to a locked file)
        with suppress(OSError):
            lock_file.write_text(f"{os.getpid()}\n", encoding="ascii")
        yield
    finally:
        lock.release()


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` so that a crash at any moment leaves the old file or the new one.

    The bytes go to a temporary file in the same directory, are flushed to disk,
    and the file is renamed over ``path`` (an atomic step on POSIX and Windows).
    A failure raises :class:`WriteError` naming ``path``.
    """
    path = Path(path)
    with _writing(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the usual permissions
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise


def _format(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


class ProgressLog:
    """A CSV file with a header and one row per episode, kept in step with an agent's history.

    :meth:`sync` appends the rows not yet in the file as complete lines in one
    write, then flushes them to disk. It first repairs the file: an empty file is
    written again from ``history``, a last line cut short by a crash is dropped, and rows beyond ``len(history)`` (written after
    the checkpoint being resumed) are removed by an atomic rewrite; a file of an
    avq of before some of the columns is written again from ``history``. So after
    any ``sync`` the file holds exactly one row per episode of ``history``.
    """

    def __init__(self, path: str | os.PathLike, columns: Sequence[str]) -> None:
        self.path = Path(path)
        self.columns = tuple(columns)
        self._header = ",".join(self.columns) + "\n"
        self._rows: int | None = None  # rows in the file, once read

    def _read_rows(self) -> int:
        """Complete rows in the file, after dropping a torn last line and checking the header."""
        if not self.path.exists():
            atomic_write_bytes(self.path, self._header.encode())
            return 0
        data = self.path.read_bytes()
        if not data.strip():  # (emptied by hand, or by a disk that lost it): its rows are made again from the history
            atomic_write_bytes(self.path, self._header.encode())
            return 0
        if not data.startswith(self._header.encode()):
            first = data[: data.find(b"\n")].decode(errors="replace").split(",")
            if first[0] == self.columns[0] and set(first) < set(self.columns):
                # Written by an avq of before some of the columns: made again from the history, which holds them.
                atomic_write_bytes(self.path, self._header.encode())
                return 0
            raise ValueError(
                f"{self.path}: not a progress file written by avq (header {self._header.strip()!r} expected); "
                f"move it away (or delete it) and run again: avq writes it anew, one row per episode, from the "
                "agent's history (a checkpoint holds every episode's)"
            )
        complete = data[: data.rfind(b"\n") + 1]
        if len(complete) != len(data):
            atomic_write_bytes(self.path, complete)
        return complete.count(b"\n") - 1

    def sync(self, history: Sequence[dict[str, Any]]) -> None:
        """Make the file hold exactly one row per record of ``history``."""
        if self._rows is None:
            self._rows = self._read_rows()
        n = len(history)
        if self._rows > n:
            lines = self.path.read_bytes().split(b"\n")
            atomic_write_bytes(self.path, b"\n".join(lines[: n + 1]) + b"\n")
            self._rows = n
        if self._rows == n:
            return
        text = "".join(",".join(_format(r.get(k, "")) for k in self.columns) + "\n" for r in history[self._rows : n])
        with _writing(self.path):
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
            try:
                data = text.encode()
                while data:  # one write in practice; loop only on a short write
                    data = data[os.write(fd, data) :]
                os.fsync(fd)
            finally:
                os.close(fd)
        self._rows = n
