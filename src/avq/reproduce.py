"""The paper's reproduction (``avq reproduce``): every agent and seed on a maze, its table and figures."""

from __future__ import annotations

import json
import os
import shutil
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from avq._io import atomic_write_bytes, check_output_dir, hold_directory, make_dirs
from avq.agents.base import BaseAgent, Callback
from avq.agents.registry import AGENTS, agent_class, make_agent
from avq.envs.layouts import Layout, LayoutSpec, load_layout
from avq.evaluation import evaluate_maze
from avq.figure_data import PartitionRecorder

__all__ = ["ReproduceRun", "train_maze_run", "warm_up", "reproduce"]


@dataclass
class ReproduceRun:
    """What one (agent, seed) run of the reproduction returns."""

    agent: str
    seed: int
    n_cells: int
    success_rate: float
    path_ratio: float | None
    env_steps: int
    #: Seconds of training (``learn``), after the warm-up.
    wall_s: float
    steps_per_trial: np.ndarray
    cells_per_trial: np.ndarray
    model_path: str | None
    #: Seconds this run spent in :func:`warm_up` (0.0 when its process had warmed up already).
    warmup_s: float = 0.0


#: The (agent, overrides) pairs whose kernels this process has compiled or loaded (see :func:`warm_up`).
_WARM: set[str] = set()


def warm_up(
    agent_name: str, layout: LayoutSpec, start: str = "random", overrides: dict[str, Any] | None = None
) -> float:
    """Compile (or load from Numba's cache) the kernels an agent uses on a maze, once per process.

    Two trials of learning and a greedy evaluation on a throwaway agent and environment,
    so that the timing of the runs that follow holds training alone. Returns the seconds
    it took (0.0 when this process had warmed up for this agent already).
    """
    import avq.envs  # noqa: F401  (registers the environments in a fresh worker)

    key = f"{agent_name} {sorted((overrides or {}).items())!r}"
    if key in _WARM:
        return 0.0
    t0 = time.perf_counter()
    env = gym.make("avq/GridMaze-v0", layout=layout, start=start)
    agent = make_agent(agent_name, env, seed=0, **(overrides or {}))
    agent.learn(total_episodes=2)  # (the first episode steps from Python, the next in the compiled loop)
    evaluate_maze(agent, gym.make("avq/GridMaze-v0", layout=layout, start=start))
    _WARM.add(key)
    return time.perf_counter() - t0


def train_maze_run(
    agent_name: str,
    layout: LayoutSpec,
    seed: int,
    trials: int,
    start: str = "random",
    model_path: str | None = None,
    overrides: dict[str, Any] | None = None,
    callback: Callback | None = None,
    recorder: PartitionRecorder | None = None,
) -> ReproduceRun:
    """Train one agent on a grid maze for ``trials`` episodes and evaluate its greedy policy.

    A plain top-level function of its parameters, so that it can run in any process.
    ``wall_s`` times the training alone: the kernels are compiled (or loaded) before, by
    :func:`warm_up` (``warmup_s``).
    ``callback`` goes to ``learn`` (it sees the agent after every episode). A ``recorder`` keeps views
    of the partition as it learns: the agent learns through :meth:`PartitionRecorder.learn
    <avq.figure_data.PartitionRecorder.learn>` (the same agent, in a few chunks; not with ``callback``).
    """
    if callback is not None and recorder is not None:
        raise ValueError("give a callback or a recorder, not both")
    warmup = warm_up(agent_name, layout, start, overrides)
    env = gym.make("avq/GridMaze-v0", layout=layout, start=start)
    agent = make_agent(agent_name, env, seed=seed, **(overrides or {}))
    t0 = time.perf_counter()
    if recorder is not None:
        recorder.learn(agent, trials)
    else:
        agent.learn(total_episodes=trials, callback=callback)
    wall = time.perf_counter() - t0
    eval_env = gym.make("avq/GridMaze-v0", layout=layout, start=start)
    ev = evaluate_maze(agent, eval_env)
    hist = agent.episode_history()
    if model_path is not None:
        agent.save(model_path)
    return ReproduceRun(
        agent=agent_name,
        seed=seed,
        n_cells=int(agent.n_cells),
        success_rate=float(ev["success_rate"]),
        path_ratio=ev["path_ratio"],
        env_steps=int(agent.num_timesteps),
        wall_s=float(wall),
        steps_per_trial=np.asarray(hist["steps"]),
        cells_per_trial=np.asarray(hist["n_cells"]),
        model_path=model_path,
        warmup_s=float(warmup),
    )


def _layout_label(layout: LayoutSpec) -> str:
    return layout if isinstance(layout, str) and "\n" not in layout else load_layout(layout).name


def reproduce(
    layout: LayoutSpec = "lau2002",
    seeds: Sequence[int] = tuple(range(10)),
    trials: int = 1000,
    agents: Sequence[str] = ("avq-paper", "avq", "tabular"),
    start: str = "random",
    out: str | os.PathLike = "reproduce-out",
    n_jobs: int | None = None,
    progress: bool = True,
    log: Callable[[str], None] | None = print,
    animate: bool = True,
) -> dict[str, Any]:
    """Train every agent for every seed on a maze; write ``summary.json``, the figures and the models.

    Everything is written into a new hidden directory beside ``out`` (``.NAME.partial-*``), which
    replaces ``out`` as a whole once the run is complete: files of an earlier reproduction that this
    one does not write are gone with it, and a run that stops early (an error, Ctrl-C) leaves ``out``
    as it was. ``out`` must be new, empty, or an earlier reproduction's directory (one holding its
    ``summary.json``); another directory is refused, so that nothing else is deleted.

    ``partition.png`` shows the headline agent (``avq-paper`` if it ran, else the first AVQ
    agent, else the first agent) on the seed where its greedy policy succeeds most and, beside
    it, on the one where it succeeds least; ``partition-NAME.png`` every other AVQ agent on the
    first seed; ``learning_curve.png`` all of them. With ``animate`` (and a headline agent with
    cells), ``partition.gif`` shows the headline agent's partition as it learns on its best seed (that run again, with a
    :class:`~avq.figure_data.PartitionRecorder`: the same run, since training is seeded; the best seed is known
    only once every seed has run. It learns in a few chunks that end at the recorded episodes, which costs far
    less than recording every seed as it ran would).

    Returns the summary (the content of ``summary.json``).
    """
    lay = load_layout(layout)  # fail early on a bad layout
    for name in agents:
        if name not in AGENTS:
            raise ValueError(f"unknown agent {name!r}; known agents: {', '.join(sorted(AGENTS))}")
    if trials < 1:
        raise ValueError(f"trials must be >= 1, not {trials}")
    if not seeds:
        raise ValueError("give at least one seed")
    if start not in ("random", "fixed"):
        raise ValueError(f"start must be 'random' or 'fixed', not {start!r}")
    if start == "fixed" and lay.start is None:
        raise ValueError(f"layout {lay.name} has no 'S', so start 'fixed' is impossible")
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file; give a directory for the results")
    _check_replaceable(out)
    make_dirs(out.parent)
    # The lock is beside ``out`` (hidden, ``.NAME.lock``), so that it holds while ``out`` is replaced.
    beside = out.absolute()
    with hold_directory(out, beside.parent / f".{beside.name}.lock"):
        t0 = time.perf_counter()
        with _replacing(out) as staging:
            summary = _run_and_write(staging, lay, layout, seeds, trials, agents, start, n_jobs, progress, log, animate)
        if log is not None:
            log(f"wrote {out}: {_listing(out)} ({time.perf_counter() - t0:.1f} s)")
        return summary


def _check_replaceable(out: Path) -> None:
    """Refuse an output directory that holds anything but an earlier reproduction (which is replaced whole)."""
    if not out.is_dir():
        return
    try:
        earlier = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        earlier = None
    if isinstance(earlier, dict) and {"agents", "trials"} <= set(earlier):
        return
    check_output_dir(out, "avq reproduce", why="; the reproduction replaces its directory as a whole")


@contextmanager
def _replacing(out: Path) -> Iterator[Path]:
    """A new directory beside ``out`` to write into; it replaces ``out`` when the block ends without an
    error, and is removed when the block raises (``out`` is then left as it was). ``out``'s parent exists."""
    parent = out.absolute().parent
    staging = parent / f".{out.name}.partial-{uuid.uuid4().hex[:8]}"
    staging.mkdir()
    try:
        yield staging
        if out.exists():
            old = staging.with_name(staging.name.replace(".partial-", ".old-"))
            os.replace(out, old)
            try:
                os.replace(staging, out)
            except BaseException:
                os.replace(old, out)
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(staging, out)
    finally:
        if staging.exists():
            shutil.rmtree(staging, ignore_errors=True)


def _listing(out: Path) -> str:
    """The entries of a directory, for a message: ``a.json, b.png, models/ (30 files)``."""

    def describe(p: Path) -> str:
        if not p.is_dir():
            return p.name
        n = sum(1 for _ in p.iterdir())
        return f"{p.name}/ ({n} file{'' if n == 1 else 's'})"

    entries = sorted(out.iterdir(), key=lambda p: (p.is_dir(), p.name))
    return ", ".join(describe(p) for p in entries if not p.name.startswith("."))


def _run_and_write(
    out: Path,
    lay: Layout,
    layout: LayoutSpec,
    seeds: Sequence[int],
    trials: int,
    agents: Sequence[str],
    start: str,
    n_jobs: int | None,
    progress: bool,
    log: Callable[[str], None] | None,
    animate: bool,
) -> dict[str, Any]:
    """Train, evaluate, and write summary.json, the figures and the models into ``out``; return the summary."""
    (out / "models").mkdir(parents=True, exist_ok=True)
    layout_arg: LayoutSpec = list(lay.rows)
    jobs = [(name, int(seed)) for name in agents for seed in seeds]
    n_jobs = n_jobs or min(len(jobs), os.cpu_count() or 1)
    args = [
        (name, layout_arg, seed, trials, start, str(out / "models" / f"{name}__seed{seed}.zip")) for name, seed in jobs
    ]
    if log is not None and not _kernels_cached():
        log("compiling the kernels, once for this installation (about two minutes) ...")
    # Compiled (or loaded) here, before the progress bar starts, so that its rate counts runs alone.
    warmup = sum(warm_up(name, layout_arg, start) for name in agents)
    results: list[ReproduceRun] = []
    if n_jobs == 1:
        stream = (train_maze_run(*a) for a in args)
    else:
        from joblib import Parallel, delayed

        stream = Parallel(n_jobs=n_jobs, return_as="generator")(delayed(train_maze_run)(*a) for a in args)
    if progress:
        from tqdm.auto import tqdm

        stream = tqdm(stream, total=len(jobs), unit="run", desc="reproduce")
    for res in stream:
        results.append(res)
    by = {(r.agent, r.seed): r for r in results}

    summary: dict[str, Any] = {
        "layout": _layout_label(layout),
        "n_states": lay.n_states,
        "trials": int(trials),
        "seeds": [int(s) for s in seeds],
        "warmup_s": round(warmup + sum(r.warmup_s for r in results), 3),
        "agents": {},
    }
    for name in agents:
        runs = [by[(name, int(s))] for s in seeds]
        summary["agents"][name] = {
            "n_cells": [r.n_cells for r in runs],
            "success_rate": [r.success_rate for r in runs],
            "path_ratio": [r.path_ratio for r in runs],
            "env_steps": [r.env_steps for r in runs],
            "wall_s": [round(r.wall_s, 6) for r in runs],  # (a compiled run of a small maze takes milliseconds)
        }
    atomic_write_bytes(out / "summary.json", json.dumps(summary, indent=2).encode())

    from avq.agents.base import load
    from avq.plotting import animate_partition, plot_learning_curves, plot_partition, plot_partitions

    first = int(seeds[0])
    avq_names = [n for n in agents if n.startswith("avq")]
    env = gym.make("avq/GridMaze-v0", layout=layout_arg, start=start)

    def title(name: str, seed: int, n_cells: int, which: str = "") -> str:
        return (
            f"{name}, seed {seed}{which}: {n_cells} cells for {lay.n_states} states\n"
            f"greedy policy reaches the goal from {by[(name, seed)].success_rate:.0%} of starts"
        )

    # partition.png: the headline agent where its rules work best, beside where they work worst.
    headline = "avq-paper" if "avq-paper" in agents else (avq_names or list(agents))[0]
    ranked = sorted((int(s) for s in seeds), key=lambda s: -by[(headline, s)].success_rate)  # stable: seed order
    shown = (
        [ranked[0]]
        if by[(headline, ranked[0])].success_rate == by[(headline, ranked[-1])].success_rate
        else [ranked[0], ranked[-1]]
    )

    def saved(name: str, seed: int) -> BaseAgent:
        path = by[(name, seed)].model_path
        assert path is not None  # (every run here saves its model, in models/)
        return load(path, env=env)

    models = [saved(headline, s) for s in shown]
    which = [""] if len(shown) == 1 else [f" (best of {len(seeds)} seeds)", f" (worst of {len(seeds)} seeds)"]
    plot_partitions(
        models,
        env,
        out / "partition.png",
        titles=[title(headline, s, m.n_cells, w) for s, m, w in zip(shown, models, which)],
    )
    # partition-NAME.png: every other AVQ agent's first seed.
    for name in avq_names:
        if name != headline:
            model = saved(name, first)
            plot_partition(model, env, out / f"partition-{name}.png", title=title(name, first, model.n_cells))
    from avq.figure_data import has_partition

    if animate and has_partition(agent_class(headline, "avq/GridMaze-v0")):
        recorder = PartitionRecorder(gym.make("avq/GridMaze-v0", layout=layout_arg, start=start))
        train_maze_run(headline, layout_arg, shown[0], trials, start, recorder=recorder)
        animate_partition(recorder.views(), env, out / "partition.gif", title=f"{headline}, seed {shown[0]}")
    curves = {n: [by[(n, int(s))].steps_per_trial for s in seeds] for n in agents}
    cells = {n: [by[(n, int(s))].cells_per_trial for s in seeds] for n in avq_names}
    plot_learning_curves(
        curves, out / "learning_curve.png", cells=cells or None, title=f"{summary['layout']}: steps per trial"
    )
    if log is not None:
        log(format_table(summary))
    return summary


def _kernels_cached() -> bool:
    """Whether Numba's on-disk cache already holds the fused maze loop (else the first run compiles)."""
    from avq._compile_cache import numba_cache_dir
    from avq.agents.avq_sarsa import fused

    cache_dir = Path(numba_cache_dir() or Path(fused.__file__).parent / "__pycache__")
    return cache_dir.is_dir() and any(cache_dir.rglob("fused.run_*.nbi"))


def _seconds(s: float) -> str:
    """Seconds to three significant figures, however small (``0.00412``), whole from 100 s on (``1234``)."""
    return f"{s:.0f}" if s >= 100 else f"{s:.3g}"


def format_table(summary: dict[str, Any]) -> str:
    """The reproduction's table: one row per agent, spread over seeds."""
    head = f"{'agent':<12} {'cells med [min-max]':>20} {'success mean [min-max]':>24} {'path ratio':>11} {'env steps':>10} {'seconds':>8}"
    lines = [
        f"layout {summary['layout']}: {summary['n_states']} states, {summary['trials']} trials, "
        f"{len(summary['seeds'])} seed{'s' if len(summary['seeds']) != 1 else ''}",
        head,
        "-" * len(head),
    ]
    for name, res in summary["agents"].items():
        cells = np.array(res["n_cells"])
        succ = np.array(res["success_rate"])
        ratios = [r for r in res["path_ratio"] if r is not None]
        ratio = f"{np.mean(ratios):.2f}" if ratios else "-"
        lines.append(
            f"{name:<12} {f'{np.median(cells):.0f} [{cells.min()}-{cells.max()}]':>20} "
            f"{f'{succ.mean():.0%} [{succ.min():.0%}-{succ.max():.0%}]':>24} {ratio:>11} "
            f"{np.mean(res['env_steps']):>10.0f} {_seconds(float(np.mean(res['wall_s']))):>8}"
        )
    lines.append(
        "success: greedy policy from every start; path ratio: greedy over shortest steps; "
        "env steps, seconds: training, mean per run"
    )
    if "warmup_s" in summary:
        lines.append(
            f"(seconds: training alone; the kernels were compiled or loaded before it, in "
            f"{summary['warmup_s']:.2f} s: warmup_s in summary.json)"
        )
    return "\n".join(lines)
