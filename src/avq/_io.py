"""Files avq writes: whole files atomically, per-episode CSV rows by appending complete lines."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["atomic_write_bytes", "ProgressLog"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` so that a crash at any moment leaves the old file or the new one.

    The bytes go to a temporary file in the same directory, are flushed to disk,
    and the file is renamed over ``path`` (an atomic step on POSIX and Windows).
    """
    path = Path(path)
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
    write, then flushes them to disk. It first repairs the file: a last line cut
    short by a crash is dropped, and rows beyond ``len(history)`` (written after
    the checkpoint being resumed) are removed by an atomic rewrite. So after any
    ``sync`` the file holds exactly one row per episode of ``history``.
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
        if not data.startswith(self._header.encode()):
            raise ValueError(f"{self.path}: not a progress file written by avq (header {self._header.strip()!r} expected)")
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
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            data = text.encode()
            while data:  # one write in practice; loop only on a short write
                data = data[os.write(fd, data):]
            os.fsync(fd)
        finally:
            os.close(fd)
        self._rows = n
