"""The ``avq`` command line: ``avq reproduce``, ``train``, ``evaluate``, ``plot``, ``sweep`` and ``tune``.

Every user mistake ends with a one-line message on stderr and exit code 2.

:func:`main` is the console entry point (``avq = "avq.cli:main"``, and ``python -m avq.cli``);
the parser is in :mod:`avq.cli.parser` (:func:`build_parser`, from which the docs generate the
CLI reference) and what each subcommand does in :mod:`avq.cli.commands`.
"""

from __future__ import annotations

import atexit
import gc
import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager

from avq.cli.commands import UsageError, key_values
from avq.cli.parser import build_parser

__all__ = ["UsageError", "build_parser", "key_values", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``avq`` with ``argv`` (default: the process's arguments) and return its exit code."""
    _end_without_collecting()
    with _fewer_collections():
        return _run(argv)


#: Gymnasium's errors that say what its user must do (install an extra, give an argument); its others are bugs.
_GYM_USER_ERRORS = ("DependencyNotInstalled", "MissingArgument")


def _run(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "command", None):
            parser.print_help()
            return 2
        return int(args.func(args) or 0)
    except UsageError as exc:
        print(f"avq: error: {exc}", file=sys.stderr)
        return 2
    except (ValueError, OSError) as exc:  # bad values, and paths that cannot be read or written
        if os.environ.get("AVQ_DEBUG"):
            raise
        print(f"avq: error: {(str(exc).splitlines() or [type(exc).__name__])[0]}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("avq: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        gym_error = sys.modules.get("gymnasium.error")  # (Gymnasium's errors for a user's mistake: a missing extra)
        for_users = tuple(getattr(gym_error, name) for name in _GYM_USER_ERRORS if hasattr(gym_error, name))
        if not isinstance(exc, for_users) or os.environ.get("AVQ_DEBUG"):
            raise
        message = (str(exc).splitlines() or ["(no message)"])[0]
        print(f"avq: error: the environment raised {type(exc).__name__}: {message}", file=sys.stderr)
        return 2


@contextmanager
def _fewer_collections() -> Iterator[None]:
    """While a command runs, the garbage collector's youngest generation is collected after 100 000 new
    objects instead of 700 (as mypy does); as it was again after.

    A command makes millions of objects as it loads its libraries and kernels (Numba's types, Matplotlib's
    artists), most of them kept to its end, and each collection goes over the young ones again (every
    tenth over the older ones too): ``avq reproduce`` spent 0.25-0.4 s in some 300 collections, and about
    0.1 s in 3 with this. Garbage held in cycles waits longer to be collected: at most some 100 000 objects.
    """
    threshold = gc.get_threshold()
    if threshold[0]:  # (0: the collector is off)
        gc.set_threshold(max(threshold[0], 100_000), *threshold[1:])
    try:
        yield
    finally:
        gc.set_threshold(*threshold)


def _end_without_collecting() -> None:
    """Spare the process's end the garbage collector (once per process; nothing changes before its end).

    As it ends, Python clears every module and runs its cycle collector over all that is left, more than
    100 000 objects once Numba's kernels and Matplotlib are loaded: 0.6-0.7 s at the end of ``avq
    reproduce``, whose files are written by then. Frozen (:func:`gc.freeze`) at exit, they are left to the
    operating system, which takes the process's memory back anyway; 0.1 s. (Python does not promise to
    finalize the objects still alive at exit either way.)
    """
    global _ENDING_FROZEN
    if not _ENDING_FROZEN:
        atexit.register(gc.freeze)
        _ENDING_FROZEN = True


_ENDING_FROZEN = False
