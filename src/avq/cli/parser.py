"""The ``avq`` command line's argument parser: every subcommand, option and help text.

Apart from the commands' bodies (:mod:`avq.cli.commands`) so that the interface reads in one
place; the docs generate the CLI reference from :func:`build_parser`. The parser reports a
mistake as a :class:`~avq.cli.commands.UsageError` (one line, no usage dump).
"""

from __future__ import annotations

import argparse
from typing import Any, NoReturn

from avq.cli.commands import UsageError, cmd_evaluate, cmd_plot, cmd_reproduce, cmd_sweep, cmd_train
from avq.tune.cli import add_from_study_options, add_tune_command

__all__ = ["build_parser", "ENV_HELP", "positive_int"]

#: What --env takes, for every command that has it.
ENV_HELP = (
    "registered Gymnasium id, e.g. MountainCar-v0 or avq/RobotMaze-v0, or MODULE:ID for an environment "
    "that a module of yours registers when imported (imported from the working directory, as python -m does)"
)


class _Parser(argparse.ArgumentParser):
    #: The subcommands: name -> (its parser, its one-line help), in order (filled by :func:`build_parser`).
    commands: dict[str, tuple[argparse.ArgumentParser, str]]

    def error(self, message: str) -> NoReturn:  # one line, no usage dump
        raise UsageError(f"{self.prog}: {message} (see '{self.prog} --help')")


def _int_at_least(name: str, low: int):
    """An argparse type: an integer >= ``low``, with a message naming the option."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, not {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"{name} must be >= {low}, not {value}")
        return value

    return parse


def positive_int(name: str):
    return _int_at_least(name, 1)


def _nonnegative_int(name: str):
    return _int_at_least(name, 0)


_NO_PROGRESS_HELP = "hide the progress bar (hidden anyway when stderr is not a terminal)"
_LOAD_ENV_HELP = (
    "the environment to load the model with instead of the one it records: an id, or MODULE:ID for an id "
    "that a module of yours registers (as in 'nav3d:user/Nav3D-v0')"
)


def build_parser() -> _Parser:
    """The ``avq`` parser: its subcommands, each with ``func`` (its ``cmd_NAME``) as the default to call, also
    listed in its ``commands`` (name -> (parser, one-line help)) for the reference pages."""
    parser = _Parser(prog="avq", description="Reinforcement learning with adaptive vector quantization.")
    from avq import __version__

    parser.add_argument("--version", action="version", version=f"avq {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    parser.commands = {}

    def command(name: str, **kwargs: Any) -> argparse.ArgumentParser:
        parser.commands[name] = (sub.add_parser(name, **kwargs), kwargs.get("help", ""))
        return parser.commands[name][0]

    rep = command(
        "reproduce",
        help="reproduce the paper's maze experiment",
        description="Train each agent for each seed on the maze, print a table, and write into --out: "
        "summary.json (the table's numbers), partition.png (the cells of the headline agent, avq-paper if it "
        "ran, on its best and its worst seed), partition-NAME.png (those of each further AVQ agent, first seed), "
        "partition.gif (the headline agent's cells as it learns, on its best seed; not with --no-animation), "
        "learning_curve.png, and models/NAME__seedS.zip "
        "(every trained agent; 'avq evaluate' reads them). The files are written beside --out first and "
        "replace it as a whole when all are done: files of an earlier reproduction that this run does not "
        "write are removed, and a run that stops early leaves --out as it was. A directory holding anything "
        "but an earlier reproduction is refused.",
    )
    rep.add_argument("--layout", default="lau2002", help="preset name or layout file (default lau2002)")
    rep.add_argument("--seeds", type=positive_int("--seeds"), default=10, help="number of seeds 0..N-1 (default 10)")
    rep.add_argument("--trials", type=positive_int("--trials"), default=1000, help="trials per run (default 1000)")
    rep.add_argument("--agents", default="avq-paper,avq,tabular", help="comma-separated agent names")
    rep.add_argument("--start", choices=["random", "fixed"], default="random", help="start positions (default random)")
    rep.add_argument("--out", default="reproduce-out", help="output directory (default reproduce-out)")
    rep.add_argument(
        "--jobs",
        type=positive_int("--jobs"),
        default=1,
        help="parallel processes (default 1: the compiled loops make one process fastest here)",
    )
    rep.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    rep.add_argument(
        "--no-animation",
        action="store_true",
        help="do not write partition.gif, the animation of the headline agent's cells and greedy "
        "actions as it learns (on its best seed; a few seconds)",
    )
    rep.set_defaults(func=cmd_reproduce)

    tr = command(
        "train",
        help="train one agent on any registered Gymnasium environment",
        description="Train an agent and write config.yml, progress.csv, checkpoint.zip, model.zip and summary.json "
        "into --out. A stopped run continues exactly with --resume DIR. Another avq process writing into --out "
        "makes it refuse.",
    )
    tr.add_argument(
        "--env",
        help=ENV_HELP,
    )
    from avq.agents.registry import AGENTS

    tr.add_argument("--agent", help=f"agent name (default avq): {', '.join(AGENTS)}")
    budget = tr.add_mutually_exclusive_group()
    budget.add_argument("--episodes", type=positive_int("--episodes"), help="episodes to train (default 500)")
    budget.add_argument("--timesteps", type=positive_int("--timesteps"), help="environment steps to train")
    tr.add_argument("--seed", type=_nonnegative_int("--seed"), help="seed (default 0)")
    tr.add_argument("--out", help="run directory (default runs/{env}__{agent}__{seed}__{time})")
    tr.add_argument("--set", action="append", metavar="KEY=VALUE", help="agent parameter (repeatable)")
    tr.add_argument(
        "--env-kwargs", action="append", metavar="KEY=VALUE", help="argument to gymnasium.make (repeatable)"
    )
    tr.add_argument("--config", help="YAML file with env, env_kwargs, agent, params, seed, episodes|timesteps, out")
    tr.add_argument(
        "--checkpoint-every",
        type=positive_int("--checkpoint-every"),
        metavar="N",
        help="save DIR/checkpoint.zip and progress rows every N episodes (default 100)",
    )
    tr.add_argument("--resume", metavar="DIR", help="continue the stopped run in DIR from its last checkpoint")
    tr.add_argument(
        "--animate",
        action="store_true",
        help="also write DIR/partition.gif: the cells and their greedy actions as they learn, up to "
        "about 100 frames evenly spaced over the episodes (avq/GridMaze-v0 and avq/RobotMaze-v0; "
        "agents with cells)",
    )
    tr.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    add_from_study_options(tr)
    tr.set_defaults(func=cmd_train)

    sw = command(
        "sweep",
        help="run a grid of configurations x seeds, locally or on a Ray or Dask cluster",
        description="avq sweep CONFIG.yml --out DIR runs every trial not yet finished in DIR and writes "
        "DIR/results.csv and DIR/curves.png (exit code 1 if a trial failed); the same command continues a "
        "stopped sweep. avq sweep report DIR ranks the configurations.",
    )
    sw.add_argument(
        "target",
        nargs="+",
        metavar="CONFIG.yml|report DIR",
        help="the sweep's YAML config, or 'report' and a sweep directory",
    )
    sw.add_argument("--out", help="the sweep's directory")
    sw.add_argument(
        "--backend",
        choices=["local", "ray", "dask"],
        default="local",
        help="local processes (default), a Ray cluster or a Dask cluster",
    )
    sw.add_argument(
        "--address",
        help="cluster address (ray: as for ray.init; dask: the scheduler); without one a local cluster is started",
    )
    sw.add_argument("--jobs", type=positive_int("--jobs"), help="parallel workers (default: CPU count)")
    sw.add_argument("--metric", help="report: the metric to rank by (default: the config's, else final_return)")
    sw.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    sw.set_defaults(func=cmd_sweep)
    add_tune_command(command)

    ev = command(
        "evaluate",
        help="evaluate a trained run's greedy policy",
        description="Load DIR/model.zip (or a model file) and report the mean and spread of the "
        "return. An episode that the environment does not end within --max-steps steps is cut "
        "there, and the report says how many were (capped in --json).",
    )
    ev.add_argument(
        "run_dir",
        metavar="DIR|MODEL.zip",
        help="a directory written by 'avq train', or a model file written by agent.save "
        "(such as avq reproduce's models/NAME__seedS.zip, or a stopped run's DIR/checkpoint.zip)",
    )
    ev.add_argument("--episodes", type=positive_int("--episodes"), default=10, help="episodes (default 10)")
    ev.add_argument(
        "--seed", type=_nonnegative_int("--seed"), default=0, help="seed of the evaluation episodes (default 0)"
    )
    ev.add_argument(
        "--max-steps",
        type=positive_int("--max-steps"),
        default=100_000,
        metavar="N",
        help="cut an episode the environment has not ended after N steps (default 100000)",
    )
    ev.add_argument("--env", metavar="ID", help=_LOAD_ENV_HELP)
    ev.add_argument("--json", action="store_true", help="print JSON")
    ev.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    ev.set_defaults(func=cmd_evaluate)

    pl = command(
        "plot",
        help="draw a trained agent's cells and greedy actions over two dimensions",
        description="Draw the greedy action of DIR/model.zip (or a model file) over two dimensions of a Box "
        "observation space, with the cells' borders and centres: a slice, the other dimensions held at --at "
        "(default the middle of their range), or with --project the cells' centres projected. The suffix of "
        "--out picks the format (.png, .pdf, .svg).",
    )
    pl.add_argument("model", metavar="DIR|MODEL.zip", help="a directory written by 'avq train', or a model file")
    pl.add_argument("--dims", default="0,1", help="the two dimensions drawn, across and up (default 0,1)")
    pl.add_argument("--at", metavar="D=V,...", help="values of other dimensions in the slice, e.g. 2=0.0,3=0.0")
    pl.add_argument("--project", action="store_true", help="project the cells' centres instead of slicing")
    pl.add_argument("--bounds", metavar="D=LOW:HIGH,...", help="the range of a dimension, e.g. 1=-3:3")
    pl.add_argument("--resolution", type=positive_int("--resolution"), default=400, help="pixels per axis (400)")
    pl.add_argument("--out", help="file to write (default DIR/policy_D0-D1.png, or beside MODEL.zip)")
    pl.add_argument("--env", metavar="ID", help=_LOAD_ENV_HELP)
    pl.set_defaults(func=cmd_plot)
    return parser
