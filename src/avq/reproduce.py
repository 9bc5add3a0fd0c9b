"""The paper's reproduction (``avq reproduce``): every agent and seed on a maze, its table and figures."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import gymnasium as gym
import numpy as np

from avq._io import atomic_write_bytes, hold_directory, make_dirs
from avq.agents.registry import AGENTS, make_agent
from avq.envs.layouts import Layout, LayoutSpec, load_layout
from avq.evaluation import evaluate_maze

__all__ = ["ReproduceRun", "train_maze_run", "reproduce"]


@dataclass
class ReproduceRun:
    """What one (agent, seed) run of the reproduction returns."""

    agent: str
    seed: int
    n_cells: int
    success_rate: float
    path_ratio: float | None
    env_steps: int
    wall_s: float
    steps_per_trial: np.ndarray
    cells_per_trial: np.ndarray
    model_path: str | None


def train_maze_run(
    agent_name: str,
    layout: LayoutSpec,
    seed: int,
    trials: int,
    start: str = "random",
    model_path: str | None = None,
    overrides: dict[str, Any] | None = None,
) -> ReproduceRun:
    """Train one agent on a grid maze for ``trials`` episodes and evaluate its greedy policy.

    A plain top-level function of its parameters, so that it can run in any process.
    """
    import avq.envs  # noqa: F401  (registers the environments in a fresh worker)

    t0 = time.perf_counter()
    env = gym.make("avq/GridMaze-v0", layout=layout, start=start)
    agent = make_agent(agent_name, env, seed=seed, **(overrides or {}))
    agent.learn(total_episodes=trials)
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
) -> dict[str, Any]:
    """Train every agent for every seed on a maze; write ``summary.json`` and the figures.

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
    # The lock is beside ``out`` (hidden, ``.NAME.lock``), so that it holds whatever happens to ``out`` itself.
    make_dirs(out.parent)
    beside = out.absolute()
    with hold_directory(out, beside.parent / f".{beside.name}.lock"):
        return _reproduce(lay, layout, seeds, trials, agents, start, out, n_jobs, progress, log)


def _reproduce(lay: Layout, layout: LayoutSpec, seeds: Sequence[int], trials: int, agents: Sequence[str], start: str,
               out: Path, n_jobs: int | None, progress: bool, log: Callable[[str], None] | None) -> dict[str, Any]:
    """:func:`reproduce` once its arguments are checked and ``out`` is held."""
    make_dirs(out / "models")
    layout_arg: LayoutSpec = list(lay.rows)
    jobs = [(name, int(seed)) for name in agents for seed in seeds]
    n_jobs = n_jobs or min(len(jobs), os.cpu_count() or 1)
    args = [(name, layout_arg, seed, trials, start, str(out / "models" / f"{name}__seed{seed}.zip"))
            for name, seed in jobs]
    t0 = time.perf_counter()
    if log is not None and not _kernels_cached():
        log("compiling the kernels, once for this installation (30-60 s) ...")
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
        "agents": {},
    }
    for name in agents:
        runs = [by[(name, int(s))] for s in seeds]
        summary["agents"][name] = {
            "n_cells": [r.n_cells for r in runs],
            "success_rate": [r.success_rate for r in runs],
            "path_ratio": [r.path_ratio for r in runs],
            "env_steps": [r.env_steps for r in runs],
            "wall_s": [round(r.wall_s, 3) for r in runs],
        }
    atomic_write_bytes(out / "summary.json", json.dumps(summary, indent=2).encode())

    from avq.agents.base import load
    from avq.plotting import plot_learning_curves, plot_partition

    first = int(seeds[0])
    avq_names = [n for n in agents if n.startswith("avq")]
    env = gym.make("avq/GridMaze-v0", layout=layout_arg, start=start)
    figures = []
    # The partition of every AVQ agent's first seed (or of the first agent's, with none):
    # partition.png for the first, partition-NAME.png for the others.
    for k, name in enumerate(avq_names or list(agents[:1])):
        model = load(by[(name, first)].model_path, env=env)
        success = by[(name, first)].success_rate
        figures.append(out / ("partition.png" if k == 0 else f"partition-{name}.png"))
        plot_partition(
            model, env, figures[-1],
            title=f"{name}, seed {first}: {model.n_cells} cells for {lay.n_states} states, "
                  f"greedy policy reaches the goal from {success:.0%} of starts",
        )
    curves = {n: [by[(n, int(s))].steps_per_trial for s in seeds] for n in agents}
    cells = {n: [by[(n, int(s))].cells_per_trial for s in seeds] for n in avq_names}
    plot_learning_curves(curves, out / "learning_curve.png", cells=cells or None,
                         title=f"{summary['layout']}: steps per trial (mean, 95% t-interval over seeds)")
    if log is not None:
        log(format_table(summary))
        log(f"wrote {out / 'summary.json'}, {', '.join(map(str, figures))}, {out / 'learning_curve.png'} "
            f"({time.perf_counter() - t0:.1f} s)")
    return summary


def _kernels_cached() -> bool:
    """Whether Numba's on-disk cache already holds the fused maze loop (else the first run compiles)."""
    import numba

    from avq.agents import _fused

    cache_dir = Path(numba.config.CACHE_DIR or Path(_fused.__file__).parent / "__pycache__")
    return cache_dir.is_dir() and any(cache_dir.rglob("_fused.run_grid_maze*.nbi"))


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
            f"{np.mean(res['env_steps']):>10.0f} {np.mean(res['wall_s']):>8.2f}"
        )
    lines.append("success: greedy policy from every start; path ratio: greedy over shortest steps; "
                 "env steps, seconds: training, mean per run")
    return "\n".join(lines)
