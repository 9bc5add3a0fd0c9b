"""The command line of tuning: ``avq tune`` (run, ``report``, ``export``) and ``avq train --from-study``.

Kept beside :mod:`avq.tune` so that :mod:`avq.cli.parser` and :mod:`avq.cli.commands` only call in here.
Nothing here imports Optuna until a command runs.
"""

from __future__ import annotations

import argparse
import inspect
import shlex
import sys
from pathlib import Path
from typing import Any

__all__ = ["add_tune_command", "add_from_study_options", "from_study", "cmd_tune"]

_DESCRIPTION = (
    "avq tune --env ENV --agent NAME searches the agent's parameters with Optuna (TPE, the median pruner) in a "
    "study stored at --storage (default: DIR/study.db, a SQLite file, with --out DIR, default tune/AGENT-ENV); "
    "each trial trains on --seeds seeds and scores the mean of --metric over them. Every worker (--jobs "
    "processes here, or --backend ray|dask) and every other 'avq tune' on the same --storage and "
    "--study-name adds trials to the one study until it holds --n-trials; the same command continues a "
    "stopped study. Prints the best trials at the end and, with --out DIR, writes DIR/best.yaml (the best "
    "parameters as an entry of the agents' defaults). 'avq tune report' ranks a study's trials, 'avq tune export' prints that "
    "entry, and 'avq train --from-study STORAGE' trains with the best parameters. Needs the extra avq[tune]."
)


def add_tune_command(command: Any) -> None:
    """Add ``avq tune`` through the parser's ``command(name, **kwargs)`` helper."""
    from avq.agents.registry import AGENTS
    from avq.cli.parser import ENV_HELP, positive_int

    tu = command("tune", help="tune an agent's parameters for a task with Optuna", description=_DESCRIPTION)
    tu.add_argument(
        "action",
        nargs="?",
        choices=["run", "report", "export"],
        default="run",
        help="run (the default): tune, with every option below; report: rank a study's trials (--out or --storage, "
        "--study-name, --top); export: print its best trial as an entry of the agents' defaults (--out or --storage, "
        "--study-name)",
    )
    tu.add_argument("--env", help=ENV_HELP + " (default: the study's)")
    tu.add_argument("--agent", help=f"agent name (default: the study's, else avq): {', '.join(AGENTS)}")
    tu.add_argument("--env-kwargs", action="append", metavar="KEY=VALUE", help="argument to gymnasium.make")
    tu.add_argument("--set", action="append", metavar="KEY=VALUE", help="agent parameter fixed in every trial")
    tu.add_argument("--space", metavar="FILE.yaml", help="search space (default: the agent's 'search' in its defaults)")
    budget = tu.add_mutually_exclusive_group()
    budget.add_argument("--episodes", type=positive_int("--episodes"), help="episodes a seed (default 300)")
    budget.add_argument("--timesteps", type=positive_int("--timesteps"), help="env steps a seed")
    tu.add_argument(
        "--evaluations", type=positive_int("--evaluations"), help="reports to the pruner per trial (default 5)"
    )
    tu.add_argument("--seeds", type=positive_int("--seeds"), help="seeds per trial (default 3)")
    tu.add_argument("--seed", type=int, default=0, help="seeds the sampler and the trials' seeds (default 0)")
    tu.add_argument("--metric", help="final_return (default), eval_return or success_rate")
    tu.add_argument("--eval-episodes", type=positive_int("--eval-episodes"), help="greedy episodes (default 10)")
    tu.add_argument("--n-trials", type=int, default=20, help="trials the study holds when done (default 20)")
    tu.add_argument("--timeout", type=float, metavar="SECONDS", help="start no trial after this time")
    tu.add_argument("--jobs", type=positive_int("--jobs"), default=1, help="parallel workers (default 1)")
    tu.add_argument("--backend", choices=["local", "ray", "dask"], default="local", help="where workers run")
    tu.add_argument("--address", help="cluster address (ray, dask); without one a local cluster is started")
    tu.add_argument("--storage", metavar="URL", help="any Optuna storage URL, or a journal file (FILE.log)")
    tu.add_argument("--study-name", help="default AGENT-ENV (report, export: the storage's only study)")
    tu.add_argument("--out", metavar="DIR", help="where study.db (the default storage) and best.yaml go")
    tu.add_argument("--pruner", choices=["median", "none"], default="median", help="default median")
    tu.add_argument("--top", type=positive_int("--top"), default=10, help="trials in the report (default 10)")
    tu.set_defaults(func=cmd_tune)


def add_from_study_options(train: argparse.ArgumentParser) -> None:
    train.add_argument(
        "--from-study",
        metavar="STORAGE",
        help="train with the best trial of an 'avq tune' study (its env, agent, budget and parameters; "
        "other options win)",
    )
    train.add_argument("--study-name", help="with --from-study: the study (default: the storage's only one)")


def from_study(args: argparse.Namespace, config: dict[str, Any]) -> dict[str, Any]:
    """``config`` (of ``--config``) with the study's best trial on top."""
    from avq.tune import study_config

    best = study_config(args.from_study, args.study_name)
    return {**config, **best, "params": {**(config.get("params") or {}), **best.get("params", {})}}


def _storage(args: argparse.Namespace) -> str:
    if args.storage:
        return args.storage
    if args.out:
        return f"sqlite:///{Path(args.out).resolve() / 'study.db'}"
    raise ValueError(f"avq tune {args.action}: give the study's --storage URL (or --out DIR of its study.db)")


def cmd_tune(args: argparse.Namespace) -> int:
    """``avq tune``: tune, then print the report; ``report`` and ``export`` read a study."""
    from avq.tune import best_entry, report, require_optuna
    from avq.tune.storage import shown

    require_optuna()
    if args.action != "run":
        storage = _storage(args)
        if args.action == "report":
            print(report(storage, args.study_name, top=args.top))
            return 0
        entry = best_entry(storage, args.study_name)
        if not entry:
            raise ValueError("the study has no complete trial yet; nothing to export")
        print(entry, end="")
        return 0
    try:
        summary = _run(args)
    except KeyboardInterrupt:
        print("avq: interrupted; the study keeps its trials: the same command continues it", file=sys.stderr)
        return 130
    print(report(summary["storage"], summary["study_name"], top=args.top))
    if summary["best_yaml"]:
        print(f"wrote {summary['best_yaml']} (the best parameters as an entry of avq/agents/defaults/<agent>.yaml)")
    elif args.out is None and summary["complete"]:
        export = shlex.join(
            ["avq", "tune", "export", "--storage", shown(summary["storage"]), "--study-name", summary["study_name"]]
        )
        print(
            f"best.yaml is written with --out DIR only; '{export}' prints the best parameters as an entry of the "
            "agents' defaults"
        )
    return 0 if summary["complete"] else 1


def _run(args: argparse.Namespace) -> dict[str, Any]:
    from avq.cli.commands import key_values
    from avq.tune import tune

    # Every option named after a parameter of tune() is that parameter; the KEY=VALUE lists are read here.
    parameters = inspect.signature(tune).parameters
    options = {name: value for name, value in vars(args).items() if name in parameters}
    options["env_kwargs"] = key_values(args.env_kwargs, "--env-kwargs") if args.env_kwargs else None
    options["fixed"] = key_values(args.set, "--set") if args.set else None
    return tune(**options)
