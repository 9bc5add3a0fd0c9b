"""The ``avq`` command line.

Every user mistake ends with a one-line message on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

__all__ = ["main"]


class UsageError(Exception):
    """A mistake of the user's, reported in one line with exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, no usage dump
        raise UsageError(f"{self.prog}: {message} (see '{self.prog} --help')")


def _positive_int(name: str):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, not {text!r}") from None
        if value < 1:
            raise argparse.ArgumentTypeError(f"{name} must be >= 1, not {value}")
        return value

    return parse


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from avq.envs.layouts import load_layout
    from avq.experiments import reproduce

    agents = [a.strip() for a in args.agents.split(",") if a.strip()]
    if not agents:
        raise UsageError("--agents needs at least one agent name")
    try:
        load_layout(args.layout)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    reproduce(
        layout=args.layout,
        seeds=list(range(args.seeds)),
        trials=args.trials,
        agents=agents,
        start=args.start,
        out=args.out,
        n_jobs=args.jobs,
        progress=not args.no_progress,
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="avq", description="Reinforcement learning with adaptive vector quantization.")
    from avq import __version__

    parser.add_argument("--version", action="version", version=f"avq {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    rep = sub.add_parser(
        "reproduce",
        help="reproduce the paper's maze experiment",
        description="Train each agent for each seed on the maze, print a table, write summary.json, "
        "partition.png and learning_curve.png.",
    )
    rep.add_argument("--layout", default="lau2002", help="preset name or layout file (default lau2002)")
    rep.add_argument("--seeds", type=_positive_int("--seeds"), default=10, help="number of seeds 0..N-1 (default 10)")
    rep.add_argument("--trials", type=_positive_int("--trials"), default=1000, help="trials per run (default 1000)")
    rep.add_argument("--agents", default="avq-paper,tabular", help="comma-separated agent names")
    rep.add_argument("--start", choices=["random", "fixed"], default="random", help="start positions (default random)")
    rep.add_argument("--out", default="reproduce-out", help="output directory (default reproduce-out)")
    rep.add_argument("--jobs", type=_positive_int("--jobs"), default=None, help="parallel processes (default: cores)")
    rep.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    rep.set_defaults(func=_cmd_reproduce)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
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
    except (ValueError, FileNotFoundError) as exc:
        print(f"avq: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("avq: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
