"""The ``avq`` command line.

Every user mistake ends with a one-line message on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from typing import Sequence

from avq._io import WriteError

__all__ = ["UsageError", "key_values", "main"]


class UsageError(Exception):
    """A mistake of the user's, reported in one line with exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, no usage dump
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


def _positive_int(name: str):
    return _int_at_least(name, 1)


def _nonnegative_int(name: str):
    return _int_at_least(name, 0)


_NO_PROGRESS_HELP = "hide the progress bar (hidden anyway when stderr is not a terminal)"


def _progress(args: argparse.Namespace) -> bool:
    """Whether to draw progress bars: not with --no-progress, nor into a file or pipe."""
    return not args.no_progress and sys.stderr.isatty()


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from avq.envs.layouts import load_layout
    from avq.reproduce import reproduce

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
        progress=_progress(args),
        animate=not args.no_animation,
    )
    return 0


_CONFIG_KEYS = {"env", "env_kwargs", "agent", "params", "seed", "episodes", "timesteps", "out", "checkpoint_every",
                "avq_version"}


def key_values(pairs: list[str], flag: str) -> dict:
    """``key=value`` pairs, values read as YAML scalars (``0.5``, ``true``, ``[1, 2]``, ``null``; ``None`` is read
    as ``null`` too, since the errors say "or None")."""
    import yaml

    out = {}
    for item in pairs or []:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise UsageError(f"{flag} expects key=value, not {item!r}")
        if not text.strip():
            raise UsageError(f"{flag} {key}: the value is empty; give {flag} {key}=VALUE (for None: {key}=null)")
        try:
            value = yaml.safe_load(text)
            read = str(value).count("#") >= text.count("#")  # (False: a '#' was read as a comment)
        except yaml.YAMLError:
            value, read = None, False
        if not read and "#" not in text:
            raise UsageError(f"{flag} {key}: cannot read the value {text!r} as YAML")
        if not read:
            inner = text.strip()
            quoted = (f"[{', '.join(repr(v.strip()) for v in inner[1:-1].split(','))}]"
                      if inner.startswith("[") and inner.endswith("]") else repr(inner))
            raise UsageError(f"{flag} {key}: cannot read the value {text!r}: in YAML '#' starts a comment; "
                             f"quote the text that holds it: {flag} \"{key}={quoted}\"")
        out[key] = None if isinstance(value, str) and value in ("None", "none") else value  # (Python's spelling)
    return out


def _load_config(path: str) -> dict:
    import yaml

    try:
        with open(path, encoding="utf-8") as f:
            config = yaml.safe_load(f)
    except OSError as exc:
        raise UsageError(f"cannot read config {path}: {exc.strerror}") from None
    except yaml.YAMLError as exc:
        raise UsageError(f"config {path} is not valid YAML: {' '.join(str(exc).split())}") from None
    if config is None:
        config = {}
    if not isinstance(config, dict):
        raise UsageError(f"config {path} must be a mapping of keys to values")
    unknown = sorted(set(config) - _CONFIG_KEYS)
    if unknown:
        raise UsageError(f"config {path}: unknown key {unknown[0]!r}; known keys: {', '.join(sorted(_CONFIG_KEYS))}")
    for key in ("params", "env_kwargs"):
        if config.get(key) is not None and not isinstance(config[key], dict):
            raise UsageError(f"config {path}: {key!r} must be a mapping")
    for key in ("env", "agent", "out"):
        if config.get(key) is not None and not isinstance(config[key], str):
            raise UsageError(f"config {path}: {key!r} must be a string, not {config[key]!r}")
    for key, low in (("seed", 0), ("episodes", 1), ("timesteps", 1), ("checkpoint_every", 1)):
        value = config.get(key)
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < low):
            raise UsageError(f"config {path}: {key!r} must be an integer >= {low}, not {value!r}")
    if config.get("episodes") is not None and config.get("timesteps") is not None:
        raise UsageError(f"config {path}: give 'episodes' or 'timesteps', not both")
    return config


def _print_train_summary(summary: dict) -> None:
    ret = summary["final_return_mean"]
    unit = summary.get("size_unit", "cells")
    unit = unit[:-1] if summary["n_cells"] == 1 and unit.endswith("s") else unit  # (1 cell)
    print(
        f"{summary['agent']} on {summary['env']} (seed {summary['seed']}): {summary['episodes']} episodes, "
        f"{summary['env_steps']} env steps, {summary['n_cells']} {unit}, "
        f"mean return of the last 10% "
        f"{'-' if ret is None else f'{ret:.2f}'}, {summary['wall_s']:.1f} s -> {summary['out']}"
    )


def _cmd_train(args: argparse.Namespace) -> int:
    from avq.runs import resume_train, train

    if args.resume:
        given = [flag for flag, value in (("--env", args.env), ("--agent", args.agent), ("--episodes", args.episodes),
                                          ("--timesteps", args.timesteps), ("--seed", args.seed), ("--out", args.out),
                                          ("--set", args.set), ("--env-kwargs", args.env_kwargs),
                                          ("--config", args.config), ("--checkpoint-every", args.checkpoint_every),
                                          ("--animate", args.animate or None))
                 if value is not None]
        if given:
            raise UsageError(f"--resume continues a run as its config.yml says; drop {given[0]}")
        if os.path.isfile(args.resume):
            raise UsageError(f"--resume {args.resume} is a file; give the run directory that holds it")
        if not os.path.isdir(args.resume):
            raise UsageError(f"--resume {args.resume}: no such run directory")
        try:
            summary = resume_train(args.resume, progress=_progress(args))
        except KeyboardInterrupt:
            return _interrupted(args.resume)
        except WriteError as exc:
            raise _stopped_by(exc, args.resume) from None
        if summary.get("already_finished"):
            print(f"{args.resume} is already finished; nothing to do")
        _print_train_summary(summary)
        return 0
    config = _load_config(args.config) if args.config else {}
    env_id = args.env or config.get("env")
    if not env_id:
        raise UsageError("--env is required (or 'env' in --config)")
    agent = args.agent or config.get("agent") or "avq"
    params = {**(config.get("params") or {}), **key_values(args.set, "--set")}
    env_kwargs = {**(config.get("env_kwargs") or {}), **key_values(args.env_kwargs, "--env-kwargs")}
    episodes, timesteps = args.episodes, args.timesteps
    if episodes is None and timesteps is None:
        episodes, timesteps = config.get("episodes"), config.get("timesteps")
        if episodes is None and timesteps is None:
            episodes = 500
    seed = args.seed if args.seed is not None else config.get("seed", 0)
    every = args.checkpoint_every or config.get("checkpoint_every") or 100
    from avq.runs import default_run_dir

    out = args.out or config.get("out") or str(default_run_dir(env_id, agent, seed))
    recorder = _partition_recorder(env_id, agent, env_kwargs) if args.animate else None
    try:
        summary = train(
            env_id, agent, episodes=episodes, timesteps=timesteps, seed=seed, params=params,
            env_kwargs=env_kwargs, out=out, progress=_progress(args), checkpoint_every=every, log=print,
            callback=recorder,
        )
    except KeyboardInterrupt:
        return _interrupted(out)
    except WriteError as exc:
        raise _stopped_by(exc, out) from None
    _print_train_summary(summary)
    if recorder is not None:
        from avq.plotting import animate_partition

        views = recorder.views()
        gif = animate_partition(views, recorder.env, os.path.join(summary["out"], "partition.gif"),
                                title=f"{agent} on {env_id}, seed {seed}")
        print(f"wrote {gif} ({len(views)} frames)")
    return 0


#: The environments whose partition ``avq train --animate`` draws.
_ANIMATED_ENVS = ("avq/GridMaze-v0", "avq/RobotMaze-v0")


def _partition_recorder(env_id: str, agent: str, env_kwargs: dict):
    """The ``learn`` callback of ``--animate``, after checking that there is a partition to draw."""
    from avq.agents.registry import AGENTS, agent_class
    from avq.figure_data import PartitionRecorder, has_partition
    from avq.runs import make_env

    if env_id not in _ANIMATED_ENVS:
        raise UsageError(f"--animate draws the partition of a maze ({' or '.join(_ANIMATED_ENVS)}), not of {env_id}; "
                         "drop --animate or choose one of those")
    if agent in AGENTS and not has_partition(agent_class(agent, env_id)):
        with_cells = ", ".join(name for name in AGENTS if has_partition(agent_class(name, env_id)))
        raise UsageError(f"--animate draws an agent's cells, and {agent} has none; drop --animate or choose an "
                         f"agent with cells: {with_cells}")
    return PartitionRecorder(make_env(env_id, env_kwargs))


def _how_to_continue(run_dir: str) -> str:
    """Where a stopped run can continue from, and the command that continues it."""
    from avq.agents.base import load

    checkpoint = os.path.join(run_dir, "checkpoint.zip")
    where = "before its first checkpoint"
    if os.path.exists(checkpoint):
        try:
            where = f"at its checkpoint after episode {load(checkpoint).num_episodes}"
        except (ValueError, OSError):
            pass
    return f"the run stopped {where}. Continue it with: avq train --resume {run_dir}"


def _interrupted(run_dir: str) -> int:
    """Ctrl-C during a run: say where it can continue from."""
    print(f"avq: interrupted; {_how_to_continue(run_dir)}", file=sys.stderr)
    return 130


def _stopped_by(exc: WriteError, run_dir: str) -> Exception:
    """A failed write (a full disk, say): once the run has begun, also say how to continue it."""
    begun, finished = (os.path.isfile(os.path.join(run_dir, name)) for name in ("config.yml", "summary.json"))
    if not begun or finished:
        return exc  # not a run that this write stopped
    return UsageError(f"{exc}; {_how_to_continue(run_dir)}")


def _cmd_evaluate(args: argparse.Namespace) -> int:
    import json

    from avq.runs import evaluate_run

    report = evaluate_run(args.run_dir, episodes=args.episodes, seed=args.seed, max_steps=args.max_steps,
                          progress=_progress(args))
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    line = (
        f"{report['agent']} on {report['env']}: return {report['mean_return']:.2f} ± {report['std_return']:.2f} "
        f"over {report['episodes']} episodes, {report['mean_steps']:.1f} steps, "
        f"{report['n_cells']} {report.get('size_unit', 'cells')}"
    )
    if report["success_rate"] is not None:
        line += f", success {report['success_rate']:.0%}"
    print(line)
    if report["capped"]:
        print(f"{report['capped']} of {report['episodes']} episodes did not end within --max-steps "
              f"{report['max_steps']} and were cut there (their return is that of the first {report['max_steps']} "
              "steps)")
    if "maze_success_rate" in report:
        ratio = report["maze_path_ratio"]
        print(f"greedy policy from every start: success {report['maze_success_rate']:.0%}, "
              f"path ratio {'-' if ratio is None else f'{ratio:.2f}'}")
    return 0


def _cmd_sweep(args: argparse.Namespace) -> int:
    from avq.sweep import SweepInterrupted, report, run_sweep

    if args.target[0] == "report":
        if len(args.target) != 2:
            raise UsageError("usage: avq sweep report DIR [--metric NAME]")
        for flag, value in (("--out", args.out), ("--address", args.address), ("--jobs", args.jobs)):
            if value is not None:
                raise UsageError(f"avq sweep report takes no {flag}")
        print(report(args.target[1], metric=args.metric))
        return 0
    if len(args.target) != 1:
        raise UsageError(f"avq sweep takes one config file, not {' '.join(args.target)}")
    if not args.out:
        raise UsageError("--out DIR is required: the sweep writes its trials and results there")
    if args.metric is not None:
        raise UsageError("--metric is for 'avq sweep report DIR'; set 'metric' in the config for the default")
    if os.path.isdir(args.target[0]):
        raise UsageError(f"{args.target[0]} is a directory; give the sweep's YAML config "
                         "(or 'avq sweep report DIR' to rank a finished sweep)")
    if not os.path.isfile(args.target[0]):
        raise UsageError(f"no such sweep config: {args.target[0]}")
    try:
        rows = run_sweep(args.target[0], args.out, backend=args.backend, address=args.address, jobs=args.jobs,
                     progress=_progress(args), log=print)
    except SweepInterrupted as stop:
        again = ["avq", "sweep", args.target[0], "--out", args.out]
        for flag, value in (("--backend", None if args.backend == "local" else args.backend),
                            ("--address", args.address), ("--jobs", args.jobs)):
            again += [flag, str(value)] if value is not None else []
        print(f"avq: interrupted; {stop.finished} of {stop.total} trials finished and are kept in {args.out}. "
              f"Continue the sweep with: {shlex.join(again)}", file=sys.stderr)
        return 130
    failed = [r for r in rows if r["status"] != "ok"]
    written = [os.path.join(args.out, name) for name in ("results.csv", "curves.png")
               if os.path.exists(os.path.join(args.out, name))]
    print(f"{len(rows) - len(failed)} of {len(rows)} trials finished, {len(failed)} failed -> {', '.join(written)}")
    for r in failed[:5]:
        print(f"  failed: {r['trial']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="avq", description="Reinforcement learning with adaptive vector quantization.")
    from avq import __version__

    parser.add_argument("--version", action="version", version=f"avq {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    rep = sub.add_parser(
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
    rep.add_argument("--seeds", type=_positive_int("--seeds"), default=10, help="number of seeds 0..N-1 (default 10)")
    rep.add_argument("--trials", type=_positive_int("--trials"), default=1000, help="trials per run (default 1000)")
    rep.add_argument("--agents", default="avq-paper,avq,tabular", help="comma-separated agent names")
    rep.add_argument("--start", choices=["random", "fixed"], default="random", help="start positions (default random)")
    rep.add_argument("--out", default="reproduce-out", help="output directory (default reproduce-out)")
    rep.add_argument("--jobs", type=_positive_int("--jobs"), default=1,
                     help="parallel processes (default 1: the compiled loops make one process fastest here)")
    rep.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    rep.add_argument("--no-animation", action="store_true",
                     help="do not write partition.gif, the animation of the headline agent's cells and greedy "
                     "actions as it learns (on its best seed; a few seconds)")
    rep.set_defaults(func=_cmd_reproduce)

    tr = sub.add_parser(
        "train",
        help="train one agent on any registered Gymnasium environment",
        description="Train an agent and write config.yml, progress.csv, checkpoint.zip, model.zip and summary.json "
        "into --out. A stopped run continues exactly with --resume DIR. Another avq process writing into --out "
        "makes it refuse.",
    )
    tr.add_argument("--env", help="registered Gymnasium id, e.g. MountainCar-v0 or avq/RobotMaze-v0")
    from avq.agents.registry import AGENTS

    tr.add_argument("--agent", help=f"agent name (default avq): {', '.join(AGENTS)}")
    budget = tr.add_mutually_exclusive_group()
    budget.add_argument("--episodes", type=_positive_int("--episodes"), help="episodes to train (default 500)")
    budget.add_argument("--timesteps", type=_positive_int("--timesteps"), help="environment steps to train")
    tr.add_argument("--seed", type=_nonnegative_int("--seed"), help="seed (default 0)")
    tr.add_argument("--out", help="run directory (default runs/{env}__{agent}__{seed}__{time})")
    tr.add_argument("--set", action="append", metavar="KEY=VALUE", help="agent parameter (repeatable)")
    tr.add_argument("--env-kwargs", action="append", metavar="KEY=VALUE", help="argument to gymnasium.make (repeatable)")
    tr.add_argument("--config", help="YAML file with env, env_kwargs, agent, params, seed, episodes|timesteps, out")
    tr.add_argument("--checkpoint-every", type=_positive_int("--checkpoint-every"), metavar="N",
                    help="save DIR/checkpoint.zip and progress rows every N episodes (default 100)")
    tr.add_argument("--resume", metavar="DIR", help="continue the stopped run in DIR from its last checkpoint")
    tr.add_argument("--animate", action="store_true",
                    help="also write DIR/partition.gif: the cells and their greedy actions as they learn, up to "
                    "about 100 frames evenly spaced over the episodes (avq/GridMaze-v0 and avq/RobotMaze-v0; "
                    "agents with cells)")
    tr.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    tr.set_defaults(func=_cmd_train)

    sw = sub.add_parser(
        "sweep",
        help="run a grid of configurations x seeds, locally or on a Ray or Dask cluster",
        description="avq sweep CONFIG.yml --out DIR runs every trial not yet finished in DIR and writes "
        "DIR/results.csv and DIR/curves.png (exit code 1 if a trial failed); the same command continues a "
        "stopped sweep. avq sweep report DIR ranks the configurations.",
    )
    sw.add_argument("target", nargs="+", metavar="CONFIG.yml|report DIR",
                    help="the sweep's YAML config, or 'report' and a sweep directory")
    sw.add_argument("--out", help="the sweep's directory")
    sw.add_argument("--backend", choices=["local", "ray", "dask"], default="local",
                    help="local processes (default), a Ray cluster or a Dask cluster")
    sw.add_argument("--address", help="cluster address (ray: as for ray.init; dask: the scheduler); "
                    "without one a local cluster is started")
    sw.add_argument("--jobs", type=_positive_int("--jobs"), help="parallel workers (default: CPU count)")
    sw.add_argument("--metric", help="report: the metric to rank by (default: the config's, else final_return)")
    sw.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    sw.set_defaults(func=_cmd_sweep)

    ev = sub.add_parser("evaluate", help="evaluate a trained run's greedy policy",
                        description="Load DIR/model.zip (or a model file) and report the mean and spread of the "
                        "return. An episode that the environment does not end within --max-steps steps is cut "
                        "there, and the report says how many were (capped in --json).")
    ev.add_argument("run_dir", metavar="DIR|MODEL.zip",
                    help="a directory written by 'avq train', or a model file written by agent.save "
                    "(such as avq reproduce's models/NAME__seedS.zip)")
    ev.add_argument("--episodes", type=_positive_int("--episodes"), default=10, help="episodes (default 10)")
    ev.add_argument("--seed", type=_nonnegative_int("--seed"), default=0,
                    help="seed of the evaluation episodes (default 0)")
    ev.add_argument("--max-steps", type=_positive_int("--max-steps"), default=100_000, metavar="N",
                    help="cut an episode the environment has not ended after N steps (default 100000)")
    ev.add_argument("--json", action="store_true", help="print JSON")
    ev.add_argument("--no-progress", action="store_true", help=_NO_PROGRESS_HELP)
    ev.set_defaults(func=_cmd_evaluate)
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
    except (ValueError, OSError) as exc:  # bad values, and paths that cannot be read or written
        if os.environ.get("AVQ_DEBUG"):
            raise
        print(f"avq: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("avq: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
