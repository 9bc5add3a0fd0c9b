"""Running experiments: the paper's reproduction (``avq reproduce``)."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import gymnasium as gym
import numpy as np

from avq._io import ProgressLog, atomic_write_bytes
from avq.agents.base import PROGRESS_COLUMNS, check_int
from avq.agents.registry import AGENTS, make_agent
from avq.envs.layouts import LayoutSpec, load_layout
from avq.evaluation import evaluate_maze

__all__ = ["ReproduceRun", "train_maze_run", "reproduce", "train", "resume_train", "evaluate_run", "make_env",
           "read_run_config"]


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
    (out / "models").mkdir(parents=True, exist_ok=True)
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


# -- single training runs (``avq train`` / ``avq evaluate``) -------------------------------------------

def make_env(env_id: str, env_kwargs: dict[str, Any] | None = None) -> gym.Env:
    """``gymnasium.make`` with errors a user can act on (ValueError naming the id or argument)."""
    import avq.envs  # noqa: F401  (registers avq's environments)

    kwargs = dict(env_kwargs or {})
    try:
        return gym.make(env_id, **kwargs)
    except gym.error.Error as exc:
        raise ValueError(f"unknown environment {env_id!r} ({exc})") from None
    except TypeError as exc:
        raise ValueError(f"bad env-kwargs for {env_id!r}: {exc}") from None


def default_run_dir(env_id: str, agent: str, seed: int | None) -> Path:
    """``runs/{env}__{agent}__{seed}__{time}`` (CleanRL's naming)."""
    env_part = env_id.replace("/", "-")
    return Path("runs") / f"{env_part}__{agent}__{seed}__{int(time.time())}"


def train(
    env_id: str,
    agent: str = "avq",
    *,
    episodes: int | None = None,
    timesteps: int | None = None,
    seed: int | None = 0,
    params: dict[str, Any] | None = None,
    env_kwargs: dict[str, Any] | None = None,
    out: str | os.PathLike | None = None,
    progress: bool = True,
    checkpoint_every: int = 100,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Train one agent on one environment and write the run directory.

    Writes ``config.yml`` (everything needed to rerun: ``avq train --config``),
    ``progress.csv`` (one row per episode) and ``checkpoint.zip`` every
    ``checkpoint_every`` episodes (so that :func:`resume_train` can continue a
    stopped run exactly), then ``model.zip`` and ``summary.json``. Returns the summary.
    ``log`` gets one line before training: which defaults the agent took (``agent.defaults_used``).
    """
    import yaml

    from avq import __version__

    if (episodes is None) == (timesteps is None):
        raise ValueError("give exactly one of episodes or timesteps")
    if params and "seed" in params:
        raise ValueError("seed is not an agent parameter here: give it as seed= (on the command line, --seed)")
    check_int("checkpoint_every", checkpoint_every, 1)
    env = make_env(env_id, env_kwargs)
    model = make_agent(agent, env, seed=seed, **(params or {}))
    out = Path(out) if out is not None else default_run_dir(env_id, agent, seed)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out} is a file; give a directory for the run")
    if (out / "model.zip").exists():
        raise ValueError(f"{out} already holds a trained run; choose another --out")
    if (out / "checkpoint.zip").exists():
        raise ValueError(f"{out} holds a stopped run; continue it with 'avq train --resume {out}', or choose another --out")
    if (out / "sweep.json").exists():
        raise ValueError(f"{out} holds a sweep; choose another --out for the run")
    out.mkdir(parents=True, exist_ok=True)
    agent_params = {k: v for k, v in model.get_params().items() if k != "seed"}
    config = {
        "env": env_id,
        "env_kwargs": dict(env_kwargs or {}),
        "agent": agent,
        "params": _plain(agent_params),
        "seed": seed,
        **({"episodes": int(episodes)} if episodes is not None else {"timesteps": int(timesteps)}),
        "checkpoint_every": int(checkpoint_every),
        "avq_version": __version__,
    }
    atomic_write_bytes(out / "config.yml", yaml.safe_dump(config, sort_keys=False).encode())
    if log is not None:
        log(str(model.defaults_used))
    return _run_to_the_end(model, out, config, progress)


def resume_train(run_dir: str | os.PathLike, progress: bool = True) -> dict[str, Any]:
    """Continue a run of :func:`train` that was stopped, from its last checkpoint.

    The result is bit for bit what the run would have given without the stop.
    A finished run is left as it is (its summary is returned); a run stopped
    before its first checkpoint starts again from the beginning.
    """
    out = Path(run_dir)
    config = read_run_config(out)
    if (out / "model.zip").exists() and (out / "summary.json").exists():
        return {**json.loads((out / "summary.json").read_text(encoding="utf-8")), "already_finished": True}
    for key in ("episodes", "timesteps"):
        if config.get(key) is not None:
            check_int(f"{out / 'config.yml'}: {key}", config[key], 1)
    if (config.get("episodes") is None) == (config.get("timesteps") is None):
        raise ValueError(f"{out / 'config.yml'}: needs exactly one of 'episodes' or 'timesteps'")
    for leftover in out.glob(".*.tmp"):  # temporary files of writes that a kill interrupted
        leftover.unlink()
    env = make_env(config["env"], config.get("env_kwargs"))
    params = _recorded_params(config)
    checkpoint = out / "checkpoint.zip"
    if checkpoint.exists():
        from avq.agents.base import load

        model = load(checkpoint, env=env)
        expected = make_agent(config["agent"], env, seed=config.get("seed"), **params)
        if type(model) is not type(expected) or model.get_params() != expected.get_params():
            raise ValueError(f"{checkpoint} does not belong to this run: its agent or parameters differ from "
                             f"{out / 'config.yml'}")
    else:
        model = make_agent(config["agent"], env, seed=config.get("seed"), **params)
    return _run_to_the_end(model, out, config, progress)


def _recorded_params(config: dict[str, Any]) -> dict[str, Any]:
    """The parameters a run's ``config.yml`` records, completed with the class's own defaults.

    ``avq train`` records every parameter, so only a parameter added by a later version of avq can be
    missing; it takes the class's default (the option off, as the run had it), not the registry's
    defaults, which may have changed since (``avq`` on the mazes, say).
    """
    import inspect

    params = dict(config.get("params") or {})
    if config.get("agent") in AGENTS:
        signature = inspect.signature(AGENTS[config["agent"]][0].__init__)
        for name, p in signature.parameters.items():
            if name not in ("self", "env", "seed") and name not in params and p.default is not p.empty:
                params[name] = p.default
    return params


def _run_to_the_end(model: Any, out: Path, config: dict[str, Any], progress: bool) -> dict[str, Any]:
    """Learn what is left of the run's budget with checkpoints; write progress, model and summary."""
    every = int(config.get("checkpoint_every") or 100)
    if config.get("episodes") is not None:
        left = {"total_episodes": max(0, int(config["episodes"]) - model.num_episodes)}
    else:
        left = {"total_timesteps": max(0, int(config["timesteps"]) - model.num_timesteps)}
    model.learn(**left, progress_bar=progress, checkpoint_every=every, checkpoint_dir=out)
    ProgressLog(out / "progress.csv", PROGRESS_COLUMNS).sync(model.history_)
    model.save(out / "model.zip")
    hist = model.episode_history()
    rets = hist.get("return", np.zeros(0))
    tail = rets[-max(1, len(rets) // 10):] if len(rets) else rets
    summary = {
        "env": config["env"],
        "agent": config["agent"],
        "seed": config.get("seed"),
        "episodes": int(model.num_episodes),
        "env_steps": int(model.num_timesteps),
        "n_cells": int(model.n_cells), "size_unit": model.size_unit,
        "final_return_mean": float(np.mean(tail)) if len(tail) else None,
        "wall_s": round(model._wall_s, 3),
        "out": str(out),
    }
    atomic_write_bytes(out / "summary.json", json.dumps(summary, indent=2).encode())
    return summary


def _plain(value: Any) -> Any:
    """NumPy values and tuples as plain YAML-friendly Python values."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def read_run_config(run_dir: str | os.PathLike) -> dict[str, Any]:
    """The ``config.yml`` of a run directory, checked."""
    import yaml

    path = Path(run_dir) / "config.yml"
    if not Path(run_dir).exists():
        raise ValueError(f"{run_dir}: no such run directory")
    if Path(run_dir).is_file():
        raise ValueError(f"{run_dir} is a file; give the run directory (written by 'avq train')")
    if not path.is_file():
        raise ValueError(f"{run_dir}: no config.yml here; is this a directory written by 'avq train'?")
    try:
        config = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(config, dict) or "env" not in config or "agent" not in config:
        raise ValueError(f"{path}: needs at least the keys 'env' and 'agent'")
    return config


def evaluate_run(run_dir: str | os.PathLike, episodes: int = 10, seed: int | None = 0) -> dict[str, Any]:
    """Load a run's model and evaluate its greedy policy (and, on a maze, from every start)."""
    from avq.agents.base import load
    from avq.evaluation import evaluate_policy

    config = read_run_config(run_dir)
    env = make_env(config["env"], config.get("env_kwargs"))
    model_path = Path(run_dir) / "model.zip"
    if not model_path.is_file():
        raise ValueError(f"{run_dir}: no model.zip here; the run did not finish")
    model = load(model_path, env=env)
    result = evaluate_policy(model, env, n_episodes=episodes, seed=seed)
    report: dict[str, Any] = {
        "run": str(run_dir), "env": config["env"], "agent": config["agent"], "n_cells": int(model.n_cells),
        "size_unit": model.size_unit,
        **{k: result[k] for k in ("episodes", "mean_return", "std_return", "mean_steps", "success_rate")},
    }
    if hasattr(env.unwrapped, "layout"):
        maze = evaluate_maze(model, make_env(config["env"], config.get("env_kwargs")))
        report["maze_success_rate"] = maze["success_rate"]
        report["maze_path_ratio"] = maze["path_ratio"]
    return report
