"""A sweep's trials: one (configuration, seed) pair each, and :func:`run_trial`, which trains and evaluates one.

:func:`run_trial` is a plain top-level function of its parameters that writes its
own directory, so that a worker of any backend can import it by name and run it.
"""

from __future__ import annotations

import json
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from avq._io import ProgressLog, atomic_write_bytes, file_name_part
from avq.sweep.config import SweepConfig, _configurations, _split

__all__ = ["Trial", "plan_trials", "run_trial", "final_return"]


@dataclass(frozen=True)
class Trial:
    """One (configuration, seed) pair and where it writes."""

    index: int
    config_id: int
    agent: str
    point: dict[str, Any]
    seed_index: int
    seed: int
    dirname: str


def plan_trials(config: SweepConfig) -> list[Trial]:
    """Every trial of the sweep, numbered configuration by configuration, seed by seed."""
    out: list[Trial] = []
    for cid, (agent, point) in enumerate(_configurations(config)):
        for s, seed in enumerate(config.seeds):
            name = f"c{cid:03d}-{file_name_part(agent)}-s{s:02d}"
            out.append(Trial(len(out), cid, agent, point, s, seed, name))
    return out


def run_trial(
    trial_dir: str,
    env: str,
    env_kwargs: dict[str, Any],
    agent: str,
    params: dict[str, Any],
    seed: int,
    episodes: int | None,
    timesteps: int | None,
    eval_episodes: int = 10,
    save_model: bool = True,
) -> dict[str, Any]:
    """Train and evaluate one agent; write ``params.json``, ``progress.csv``, ``model.zip``, ``summary.json``.

    ``summary.json`` is written last, so its presence marks a finished trial;
    a finished trial is not run again (its summary is returned).
    """
    import avq.envs  # noqa: F401  (registers avq's environments in a fresh worker)
    from avq.agents.callbacks import PROGRESS_COLUMNS
    from avq.agents.registry import make_agent
    from avq.evaluation import evaluate_maze, evaluate_policy
    from avq.runs import make_env

    out = Path(trial_dir)
    done = out / "summary.json"
    if done.exists():
        return json.loads(done.read_text(encoding="utf-8"))
    out.mkdir(parents=True, exist_ok=True)
    spec = {
        "env": env,
        "env_kwargs": env_kwargs,
        "agent": agent,
        "params": params,
        "seed": seed,
        "episodes": episodes,
        "timesteps": timesteps,
        "eval_episodes": eval_episodes,
    }
    atomic_write_bytes(out / "params.json", json.dumps(spec, indent=2).encode())
    t0 = time.perf_counter()
    model = make_agent(agent, make_env(env, env_kwargs), seed=seed, **params)
    model.learn(total_episodes=episodes, total_timesteps=timesteps)
    progress = out / "progress.csv"
    if progress.exists():
        progress.unlink()  # left by an interrupted attempt: this attempt rewrites every row
    ProgressLog(progress, PROGRESS_COLUMNS).sync(model.history_)
    if save_model:
        model.save(out / "model.zip")
    summary: dict[str, Any] = {
        "final_return": final_return(model),
        "eval_return": None,
        "success_rate": None,
        "path_ratio": None,
        "n_cells": int(model.n_cells),
        "env_steps": int(model.num_timesteps),
        "episodes": int(model.num_episodes),
        "wall_s": None,
    }
    if eval_episodes:
        eval_env = make_env(env, env_kwargs)
        ev = evaluate_policy(model, eval_env, n_eval_episodes=eval_episodes, seed=seed)
        summary["eval_return"] = ev["mean_return"]
        summary["success_rate"] = ev["success_rate"]
        if hasattr(eval_env.unwrapped, "layout") and hasattr(eval_env.unwrapped.layout, "distances"):
            maze = evaluate_maze(model, make_env(env, env_kwargs))
            summary["success_rate"], summary["path_ratio"] = maze["success_rate"], maze["path_ratio"]
    summary["wall_s"] = round(time.perf_counter() - t0, 3)  # training, evaluation and saving
    atomic_write_bytes(done, json.dumps(summary, indent=2).encode())
    return summary


def final_return(model: Any) -> float | None:
    """The mean return of the last 10% of a model's episodes (at least one): a sweep's and a tuning's
    ``final_return``; None before the first episode."""
    returns = model.episode_history().get("return", np.zeros(0))
    tail = returns[-max(1, len(returns) // 10) :]
    return float(np.mean(tail)) if len(tail) else None


def _safe_trial(kwargs: dict[str, Any]) -> dict[str, Any]:
    """:func:`run_trial` that returns its error instead of raising, so one failure stops nothing."""
    try:
        return {"status": "ok", **run_trial(**kwargs)}
    except Exception as exc:  # noqa: BLE001  (any error of a trial is recorded, not raised)
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f" ({Path(last.filename).name}:{last.lineno})" if last else ""
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}{where}".replace("\n", " ")}


def _trial_kwargs(config: SweepConfig, trial: Trial, out: Path) -> dict[str, Any]:
    params, env_kwargs = _split(trial.point)
    return {
        "trial_dir": str(out / "trials" / trial.dirname),
        "env": config.env,
        "env_kwargs": {**config.env_kwargs, **env_kwargs},
        "agent": trial.agent,
        "params": {**config.params, **params},
        "seed": trial.seed,
        "episodes": config.episodes,
        "timesteps": config.timesteps,
        "eval_episodes": config.eval_episodes,
        "save_model": config.save_models,
    }
