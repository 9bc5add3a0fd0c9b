"""The ``avq`` command line: ``avq reproduce``, ``train``, ``evaluate``, ``plot``, ``sweep`` and ``tune``.

Every user mistake ends with a one-line message on stderr and exit code 2.

:func:`main` is the console entry point (``avq = "avq.cli:main"``, and ``python -m avq.cli``);
the parser is in :mod:`avq.cli.parser` (:func:`build_parser`, from which the docs generate the
CLI reference) and what each subcommand does in :mod:`avq.cli.commands`.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from avq.cli.commands import UsageError, key_values
from avq.cli.parser import build_parser

__all__ = ["UsageError", "build_parser", "key_values", "main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``avq`` with ``argv`` (default: the process's arguments) and return its exit code."""
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
        print(f"avq: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("avq: interrupted", file=sys.stderr)
        return 130
