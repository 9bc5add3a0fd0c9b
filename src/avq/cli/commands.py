"""What the ``avq`` subcommands do once their arguments are parsed (:mod:`avq.cli.parser` parses them).

One function per subcommand, ``cmd_NAME(args) -> exit code``, and what they share: reading
``--config`` and ``KEY=VALUE`` options, the summary lines, and what to say when a run stops
(Ctrl-C, a full disk) so that it can be continued. A user's mistake raises :class:`UsageError`,
which :func:`avq.cli.main` reports in one line with exit code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shlex
import sys

from avq._io import WriteError, read_yaml

__all__ = ["UsageError", "key_values", "cmd_reproduce", "cmd_train", "cmd_sweep", "cmd_evaluate", "cmd_plot"]


class UsageError(Exception):
    """A mistake of the user's, reported in one line with exit code 2."""


def _progress(args: argparse.Namespace) -> bool:
    """Whether to draw progress bars: not with --no-progress, nor into a file or pipe."""
    return not args.no_progress and sys.stderr.isatty()


def cmd_reproduce(args: argparse.Namespace) -> int:
    """``avq reproduce``: the paper's maze experiment."""
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


_CONFIG_KEYS = {
    "env",
    "env_kwargs",
    "agent",
    "params",
    "seed",
    "episodes",
    "timesteps",
    "out",
    "checkpoint_every",
    "avq_version",
}


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
            quoted = (
                f"[{', '.join(repr(v.strip()) for v in inner[1:-1].split(','))}]"
                if inner.startswith("[") and inner.endswith("]")
                else repr(inner)
            )
            raise UsageError(
                f"{flag} {key}: cannot read the value {text!r}: in YAML '#' starts a comment; "
                f'quote the text that holds it: {flag} "{key}={quoted}"'
            )
        out[key] = None if isinstance(value, str) and value in ("None", "none") else value  # (Python's spelling)
    return out


def _load_config(path: str) -> dict:
    try:
        config = read_yaml(path, f"config {path}")
    except ValueError as exc:
        raise UsageError(str(exc)) from None
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


def _size(n: int, unit: str) -> str:
    """``"12 cells"``, ``"1 cell"`` (``unit``: an agent's ``size_unit``, a plural)."""
    return f"{n} {unit[:-1] if n == 1 and unit.endswith('s') else unit}"


def _print_train_summary(summary: dict) -> None:
    ret = summary["final_return_mean"]
    print(
        f"{summary['agent']} on {summary['env']} (seed {summary['seed']}): {summary['episodes']} episodes, "
        f"{summary['env_steps']} env steps, {_size(summary['n_cells'], summary.get('size_unit', 'cells'))}, "
        f"mean return of the last 10% "
        f"{'-' if ret is None else f'{ret:.2f}'}, {summary['wall_s']:.1f} s -> {summary['out']}"
    )


def cmd_train(args: argparse.Namespace) -> int:
    """``avq train``: a new run, or ``--resume`` of a stopped one; prints the run's summary."""
    from avq.runs import resume_train, train

    if args.resume:
        given = [
            flag
            for flag, value in (
                ("--env", args.env),
                ("--agent", args.agent),
                ("--episodes", args.episodes),
                ("--timesteps", args.timesteps),
                ("--seed", args.seed),
                ("--out", args.out),
                ("--set", args.set),
                ("--env-kwargs", args.env_kwargs),
                ("--config", args.config),
                ("--from-study", args.from_study),
                ("--checkpoint-every", args.checkpoint_every),
                ("--animate", args.animate or None),
            )
            if value is not None
        ]
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
    if args.from_study:
        from avq.tune.cli import from_study

        config = from_study(args, config)
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
            env_id,
            agent,
            episodes=episodes,
            timesteps=timesteps,
            seed=seed,
            params=params,
            env_kwargs=env_kwargs,
            out=out,
            progress=_progress(args),
            checkpoint_every=every,
            log=print,
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
        gif = animate_partition(
            views,
            recorder.env,
            os.path.join(summary["out"], "partition.gif"),
            title=f"{agent} on {env_id}, seed {seed}",
        )
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
        raise UsageError(
            f"--animate draws the partition of a maze ({' or '.join(_ANIMATED_ENVS)}), not of {env_id}; "
            "drop --animate or choose one of those"
        )
    if agent in AGENTS and not has_partition(agent_class(agent, env_id)):
        with_cells = ", ".join(name for name in AGENTS if has_partition(agent_class(name, env_id)))
        raise UsageError(
            f"--animate draws an agent's cells, and {agent} has none; drop --animate or choose an "
            f"agent with cells: {with_cells}"
        )
    return PartitionRecorder(make_env(env_id, env_kwargs))


def _how_to_continue(run_dir: str) -> str:
    """Where a stopped run can continue from, and the command that continues it."""
    from avq.agents.base import load

    checkpoint = os.path.join(run_dir, "checkpoint.zip")
    where = "before its first checkpoint"
    if os.path.exists(checkpoint):
        with contextlib.suppress(ValueError, OSError):
            where = f"at its checkpoint after episode {load(checkpoint).num_episodes}"
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


def cmd_evaluate(args: argparse.Namespace) -> int:
    """``avq evaluate``: the greedy policy of a run or model file, as a line or ``--json``."""
    import json

    from avq.evaluation import SUCCESS_RULES
    from avq.runs import evaluate_run

    report = evaluate_run(
        args.run_dir,
        episodes=args.episodes,
        seed=args.seed,
        max_steps=args.max_steps,
        progress=_progress(args),
        env=args.env,
    )
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    agent = report["agent"] if report["agent"] == report["class"] else f"{report['agent']} ({report['class']})"
    line = (
        f"{agent} on {report['env']}: return {report['mean_return']:.2f} ± {report['std_return']:.2f} "
        f"over {report['episodes']} episodes, {report['mean_steps']:.1f} steps, "
        f"{_size(report['n_cells'], report['size_unit'])}"
    )
    if report["success_rate"] is not None:
        line += f", success {report['success_rate']:.0%}"
        if SUCCESS_RULES.get(report["env"]) == "truncated":
            line += " (episodes that lasted until the time limit or --max-steps)"
    print(line)
    if report["capped"]:
        print(
            f"{report['capped']} of {report['episodes']} episodes did not end within --max-steps "
            f"{report['max_steps']} and were cut there (their return is that of the first {report['max_steps']} "
            "steps)"
        )
    if "maze_success_rate" in report:
        ratio = report["maze_path_ratio"]
        print(
            f"greedy policy from every start: success {report['maze_success_rate']:.0%}, "
            f"path ratio {'-' if ratio is None else f'{ratio:.2f}'}"
        )
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """``avq sweep CONFIG --out DIR`` runs a sweep (exit code 1 if a trial failed); ``avq sweep report DIR``
    ranks one."""
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
        raise UsageError(
            f"{args.target[0]} is a directory; give the sweep's YAML config "
            "(or 'avq sweep report DIR' to rank a finished sweep)"
        )
    if not os.path.isfile(args.target[0]):
        raise UsageError(f"no such sweep config: {args.target[0]}")
    try:
        rows = run_sweep(
            args.target[0],
            args.out,
            backend=args.backend,
            address=args.address,
            jobs=args.jobs,
            progress=_progress(args),
            log=print,
        )
    except SweepInterrupted as stop:
        again = ["avq", "sweep", args.target[0], "--out", args.out]
        for flag, value in (
            ("--backend", None if args.backend == "local" else args.backend),
            ("--address", args.address),
            ("--jobs", args.jobs),
        ):
            again += [flag, str(value)] if value is not None else []
        print(
            f"avq: interrupted; {stop.finished} of {stop.total} trials finished and are kept in {args.out}. "
            f"Continue the sweep with: {shlex.join(again)}",
            file=sys.stderr,
        )
        return 130
    failed = [r for r in rows if r["status"] != "ok"]
    written = [
        os.path.join(args.out, name)
        for name in ("results.csv", "curves.png")
        if os.path.exists(os.path.join(args.out, name))
    ]
    print(f"{len(rows) - len(failed)} of {len(rows)} trials finished, {len(failed)} failed -> {', '.join(written)}")
    for r in failed[:5]:
        print(f"  failed: {r['trial']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


def cmd_plot(args: argparse.Namespace) -> int:
    """``avq plot``: the cells and greedy actions of a run or model file over two dimensions."""
    from avq.plotting import plot_model

    kwargs = {k: getattr(args, k) for k in ("dims", "at", "project", "bounds", "resolution", "out", "env")}
    print(f"wrote {plot_model(args.model, **kwargs)}")
    return 0
