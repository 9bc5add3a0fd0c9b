"""Numba's on-disk cache, keyed by a hash of avq's sources, so that compiled code can never be stale.

Why: Numba's ``cache=True`` checks a cached function against its *own* source file only. avq's
compiled loops call into other modules (``inline="always"`` helpers and other compiled functions in
``avq/rules.py``, ``avq/agents/_td.py``, ``avq/envs/*``, ...), and a cached caller goes on running the
code it compiled with the old callee after the callee's module changed: silently, in a development
checkout, and after an upgrade of avq that leaves the caller's file as it was (Numba's documentation,
"Cache invalidation fails to recognize changes in symbols defined in a different file").

What: :func:`configure`, called by ``avq/__init__.py`` before any module that defines a compiled
function is imported, hashes every ``.py`` file of the package (paths and contents) with avq's,
Numba's and NumPy's versions and the interpreter's tag, and sets ``numba.config.CACHE_DIR`` (the
``NUMBA_CACHE_DIR`` setting) to a folder named by that hash:

* ``$XDG_CACHE_HOME/avq/numba/<hash>/`` (``~/.cache/avq/numba/<hash>/`` without it), or
* ``$NUMBA_CACHE_DIR/avq-<hash>/`` when the user chose a place for Numba's cache (the environment
  variable, or ``numba.config.CACHE_DIR`` set before ``import avq``): their place, still keyed.

Any change to any source file of avq, or to those versions, gives another folder, so nothing compiled
from other sources is ever loaded. The same sources give the same folder, so the cache works as before
across processes (sweep workers included). Numba picks a function's cache folder when the function is
decorated, that is when its module is imported, and reads ``config.CACHE_DIR`` then; every module
that defines a compiled function is imported after ``avq/__init__.py`` has run this.

Why the whole contents, every time, and no cache of the hash keyed on file sizes and times: hashing
the ~0.5 MB of the package's sources costs about a millisecond (measured; ``import avq`` takes over a
second), and a key on (size, mtime) would miss exactly the case this exists for: an installer that
restores files' times (a wheel keeps them, and so may a copy or a checkout) with a change of the same
size.

The setting is process-wide: compiled functions of other packages imported in the same process also
cache into this folder (correct, as Numba checks their own files; recompiled once when avq changes).

Housekeeping: the folder is touched at each import, and :func:`prune` keeps the :data:`KEEP` most
recently used folders of avq's own cache root and removes older ones not used for :data:`GRACE_S`
seconds (the grace spares a long run of another avq version, whose workers would recompile). Only
folders whose name is a hash made here are removed, nothing else in that root.

If the folder cannot be written (a read-only home, say), a keyed folder in the temporary directory is
used instead; if none can be written, Numba's setting is left as it was and a warning says so.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

__all__ = ["source_hash", "cache_root", "prune", "configure", "KEEP", "GRACE_S"]

#: How many of the most recently used hash folders :func:`prune` always keeps.
KEEP = 3
#: A folder used less than this many seconds ago is never removed.
GRACE_S = 3600.0
#: Length of the hash in folder names (hex digits; 64 bits).
HASH_LEN = 16
#: The prefix of the hash folders inside a cache directory the user chose (``NUMBA_CACHE_DIR``).
USER_DIR_PREFIX = "avq-"

_PACKAGE_DIR = Path(__file__).resolve().parent
# The folder set by the last configure() of this process and the user's own setting it replaced.
_configured: tuple[str, str] | None = None


def source_hash(package_dir: Path = _PACKAGE_DIR) -> str:
    """A hex digest of every ``.py`` file under ``package_dir`` (relative paths and contents) and of
    the versions that change compiled code: avq's, Numba's, NumPy's and the interpreter's tag."""
    import numba
    import numpy

    from avq._version import __version__

    h = hashlib.sha256()
    for part in (__version__, numba.__version__, numpy.__version__, sys.implementation.cache_tag or ""):
        h.update(part.encode() + b"\0")
    files: list[str] = []
    for dirpath, dirnames, filenames in os.walk(package_dir):
        dirnames[:] = [d for d in dirnames if d != "__pycache__" and not d.startswith(".")]
        files.extend(os.path.join(dirpath, f) for f in filenames if f.endswith(".py"))
    for path in sorted(files):
        with open(path, "rb") as f:
            data = f.read()
        rel = os.path.relpath(path, package_dir).replace(os.sep, "/")
        h.update(f"{rel}\0{len(data)}\0".encode())
        h.update(data)
    return h.hexdigest()[:HASH_LEN]


def cache_root(user_dir: str = "", environ: os._Environ | dict = os.environ) -> tuple[Path, str]:
    """Where the hash folders go, and the prefix of their names.

    ``user_dir`` is the user's own choice of Numba's cache directory (empty for none): the folders
    then go there, named ``avq-<hash>``; else in ``$XDG_CACHE_HOME/avq/numba/`` (``~/.cache`` without
    the variable), named ``<hash>``.
    """
    if user_dir:
        return Path(user_dir).expanduser(), USER_DIR_PREFIX
    base = environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "avq" / "numba", ""


def _fallback_root() -> Path:
    """A root in the temporary directory, one per user (for when the chosen one cannot be written)."""
    uid = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    return Path(tempfile.gettempdir()) / f"avq-numba-{uid}"


def _writable(folder: Path) -> bool:
    """Make ``folder`` and check that a file can be written in it (Numba's own test of a cache folder)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        os.utime(folder)  # marks it as used, for prune()
    except OSError:
        return False
    return True


def prune(root: Path, prefix: str, current: str, keep: int = KEEP, grace_s: float = GRACE_S) -> list[Path]:
    """Remove the hash folders of ``root`` (names ``prefix`` + ``HASH_LEN`` hex digits) beyond the ``keep``
    most recently used, except ``current`` and those used less than ``grace_s`` seconds ago.

    Returns the folders removed. Anything else in ``root`` is never touched; errors are ignored (a
    folder another process is removing, say).
    """
    pattern = re.compile(re.escape(prefix) + f"[0-9a-f]{{{HASH_LEN}}}")
    try:
        entries = [e for e in os.scandir(root) if pattern.fullmatch(e.name) and e.is_dir(follow_symlinks=False)]
    except OSError:
        return []
    used = []
    for e in entries:
        with contextlib.suppress(OSError):
            used.append((e.stat(follow_symlinks=False).st_mtime, e.name))
    used.sort(reverse=True)
    now = time.time()
    removed = []
    for mtime, name in used[keep:]:
        if name == current or now - mtime < grace_s:
            continue
        shutil.rmtree(root / name, ignore_errors=True)
        removed.append(root / name)
    return removed


def numba_cache_dir() -> str:
    """Numba's cache setting in force (``numba.config.CACHE_DIR``): after :func:`configure`, the folder of
    avq's current sources; ``""`` for Numba's default (a ``__pycache__`` beside each module)."""
    from numba import config

    # (numba.config makes its settings at run time, from the environment: mypy sees none of them)
    return config.CACHE_DIR  # type: ignore[attr-defined]


def configure() -> Path | None:
    """Point Numba's cache at the folder of avq's current sources (see the module's docstring).

    Returns the folder, or ``None`` when no folder could be written (Numba's setting is then unchanged).
    """
    global _configured
    from numba import config

    user_dir = numba_cache_dir() or ""
    if _configured is not None and user_dir == _configured[0]:
        user_dir = _configured[1]  # configured before in this process: not the user's choice
    digest = source_hash()
    root, prefix = cache_root(user_dir)
    for base in (root, _fallback_root()):
        folder = base / (prefix + digest)
        if _writable(folder):
            prune(base, prefix, folder.name)
            # (a setting numba.config makes at run time: see numba_cache_dir)
            config.CACHE_DIR = str(folder)  # type: ignore[attr-defined]
            _configured = (str(folder), user_dir)
            return folder
    warnings.warn(
        f"avq: no writable folder for Numba's compilation cache (tried {root} and {_fallback_root()}); "
        "Numba's own cache setting is used, which does not see changes across avq's modules",
        RuntimeWarning,
        stacklevel=2,
    )
    return None
