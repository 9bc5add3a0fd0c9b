"""Run directories of ``avq train``, ``avq train --resume`` and ``avq evaluate``: one agent on one environment."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np

from avq._io import ProgressLog, atomic_write_bytes, check_output_dir, file_name_part, hold_directory, make_dirs
from avq._validate import check_int
from avq.agents.base import BaseAgent, Callback, NotFiniteError
from avq.agents.callbacks import PROGRESS_COLUMNS, CheckpointCallback
from avq.agents.registry import AGENTS, agent_class, make_agent
from avq.envs import as_env, split_env_id
from avq.evaluation import evaluate_maze

__all__ = ["train", "resume_train", "evaluate_run", "load_run", "make_env", "read_run_config"]


def make_env(env_id: str, env_kwargs: dict[str, Any] | None = None) -> gym.Env:
    """The environment of ``env_id`` made with ``env_kwargs``: :func:`avq.envs.as_env`, the one place ids are
    resolved (``module:id`` included; ValueErrors naming the id, the module or the argument)."""
    return as_env(env_id, **dict(env_kwargs or {}))


def default_run_dir(env_id: str, agent: str, seed: int | None) -> Path:
    """``runs/{env}__{agent}__{seed}__{time}`` (CleanRL's naming), a valid directory name on every system:
    ``runs/user-Nav3D-v0__avq__0__1763850000`` for ``mymodule:user/Nav3D-v0`` (:func:`avq._io.file_name_part`)."""
    name = "__".join(file_name_part(str(part)) for part in (split_env_id(env_id)[1], agent, seed, int(time.time())))
    return Path("runs") / name


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
    callback: Callback | None = None,
) -> dict[str, Any]:
    """Train one agent on one environment and write the run directory.

    Writes ``config.yml`` (everything needed to rerun: ``avq train --config``),
    ``progress.csv`` (one row per episode) and ``checkpoint.zip`` every
    ``checkpoint_every`` episodes (so that :func:`resume_train` can continue a
    stopped run exactly), then ``model.zip`` and ``summary.json``. Returns the summary.
    Refuses (``ValueError``) an ``out`` that holds a run or a sweep, or that another process is using.
    ``log`` gets one line before training: which defaults the agent took (``agent.defaults_used``).
    ``callback`` goes to ``learn`` (``callback(agent, record)`` after every episode).
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
    if not any((out / name).exists() for name in ("model.zip", "checkpoint.zip", "sweep.json", "config.yml")):
        check_output_dir(out, "avq train")  # (before the lock file, so that a folder of the user's stays untouched)
    with hold_directory(make_dirs(out)):
        _check_new_run_dir(out)  # (again, held: another process may have written since)
        agent_params = {k: v for k, v in model.get_params().items() if k != "seed"}
        config = {
            "env": env_id,
            "env_kwargs": dict(env_kwargs or {}),
            "agent": agent,
            "params": _plain(agent_params),
            "seed": seed,
            # (exactly one of episodes and timesteps: checked above)
            **({"episodes": int(episodes)} if episodes is not None else {"timesteps": int(cast(int, timesteps))}),
            "checkpoint_every": int(checkpoint_every),
            "avq_version": __version__,
        }
        atomic_write_bytes(out / "config.yml", yaml.safe_dump(config, sort_keys=False).encode())
        if log is not None:
            log(str(model.defaults_used))
        return _run_to_the_end(model, out, config, progress, callback)


def _check_new_run_dir(out: Path) -> None:
    """Refuse an ``out`` that holds a run, a sweep or files of the user's (:func:`avq._io.check_output_dir`)."""
    if (out / "model.zip").exists():
        raise ValueError(f"{out} already holds a trained run; choose another --out")
    if (out / "checkpoint.zip").exists():
        raise ValueError(
            f"{out} holds a stopped run; continue it with 'avq train --resume {out}', or choose another --out"
        )
    if (out / "sweep.json").exists():
        raise ValueError(f"{out} holds a sweep; choose another --out for the run")
    if (out / "config.yml").exists():
        raise ValueError(
            f"{out} holds a run stopped before its first checkpoint (its config.yml); continue it "
            f"with 'avq train --resume {out}' (from episode 0, with that config), or, to start again with other "
            f"settings, remove {out} (it holds no checkpoint: --resume too would start from episode 0) or choose "
            "another --out"
        )
    check_output_dir(out, "avq train")


def resume_train(run_dir: str | os.PathLike, progress: bool = True) -> dict[str, Any]:
    """Continue a run of :func:`train` that was stopped, from its last checkpoint.

    The result is bit for bit what the run would have given without the stop.
    A finished run is left as it is (its summary is returned); a run stopped
    before its first checkpoint starts again from the beginning.
    """
    out = Path(run_dir)
    config = read_run_config(out)
    if (out / "model.zip").exists() and (out / "summary.json").exists():  # (read only: no need to hold it)
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        return {**summary, "out": str(out), "already_finished": True}  # (as given now, not as it was given then)
    with hold_directory(out):
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
                raise ValueError(
                    f"{checkpoint} does not belong to this run: its agent or parameters differ from "
                    f"{out / 'config.yml'}"
                )
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
        signature = inspect.signature(agent_class(config["agent"], config.get("env")).__init__)
        for name, p in signature.parameters.items():
            if name not in ("self", "env", "seed") and name not in params and p.default is not p.empty:
                params[name] = p.default
    return params


def _run_to_the_end(
    model: Any, out: Path, config: dict[str, Any], progress: bool, callback: Callback | None = None
) -> dict[str, Any]:
    """Learn what is left of the run's budget with checkpoints; write progress, model and summary."""
    every = int(config.get("checkpoint_every") or 100)
    if config.get("episodes") is not None:
        left = {"total_episodes": max(0, int(config["episodes"]) - model.num_episodes)}
    else:
        left = {"total_timesteps": max(0, int(config["timesteps"]) - model.num_timesteps)}
    try:
        checkpoints = CheckpointCallback(every, out)
        model.learn(
            **left, progress_bar=progress, callback=[checkpoints] if callback is None else [callback, checkpoints]
        )
    except NotFiniteError as exc:  # (learn checkpoints at every multiple of `every`, and writes nothing else)
        done = model.num_episodes - model.num_episodes % every
        kept = (
            f"its checkpoint after episode {done} and progress.csv up to it are intact"
            if done
            else f"it had no checkpoint yet (the first comes after episode {every})"
        )
        raise NotFiniteError(
            f"{exc}; the run in {out} stopped there: {kept}; once the environment is fixed, "
            f"continue it with 'avq train --resume {out}'"
        ) from None
    ProgressLog(out / "progress.csv", PROGRESS_COLUMNS).sync(model.history_)
    model.save(out / "model.zip")
    hist = model.episode_history()
    rets = hist.get("return", np.zeros(0))
    tail = rets[-max(1, len(rets) // 10) :] if len(rets) else rets
    summary = {
        "env": config["env"],
        "agent": config["agent"],
        "seed": config.get("seed"),
        "episodes": int(model.num_episodes),
        "env_steps": int(model.num_timesteps),
        "n_cells": int(model.n_cells),
        "size_unit": model.size_unit,
        "final_return_mean": float(np.mean(tail)) if len(tail) else None,
        "wall_s": round(model.wall_s_, 3),
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


def load_run(run_dir: str | os.PathLike, env: str | None = None) -> tuple[BaseAgent, str]:
    """The trained agent of a run directory of :func:`train` (its ``model.zip``, on the environment its
    ``config.yml`` names) or of a model file written by ``agent.save`` (on the environment the file records),
    such as a stopped run's ``checkpoint.zip``, and its name: the run's agent name, or the one the file
    records (its class for a file that records none). ``env``, an id or ``module:id``
    (:func:`avq.envs.as_env`), instead of the environment the run or the file names: for a file whose own
    cannot be made here (an id registered by a module of the user's that the file does not record); made with
    the ``gymnasium.make`` arguments the run or the file records where it names the same id."""
    from avq.agents.base import load
    from avq.agents.save_util import model_file_in, recorded_env

    if not Path(run_dir).exists():
        raise ValueError(
            f"{run_dir}: no such model file or run directory; give a directory written by 'avq train' "
            "or a model file written by agent.save"
        )
    if Path(run_dir).is_file():
        try:
            env_id, env_make = recorded_env(run_dir)
        except ValueError as exc:
            raise ValueError(
                f"{exc}; give a run directory (written by 'avq train') or a model file (written by agent.save)"
            ) from None
        try:
            model = load(run_dir, env=None if env is None else _env_like(env, env_id, env_make))
        except ValueError as exc:
            hint = "" if env is not None or "pass env=" not in str(exc) else " (avq evaluate and avq plot: --env ID)"
            raise ValueError(f"{exc}{hint}") from None
        used = model.defaults_used
        return model, used.name if used is not None else type(model).__name__
    inside = model_file_in(run_dir)
    if not (Path(run_dir) / "config.yml").is_file() and inside is not None:
        raise ValueError(
            f"{run_dir}: no config.yml here (not a directory of 'avq train'); give the model file in it, {inside}"
        )
    config = read_run_config(run_dir)
    given = _env_like(env or config["env"], config["env"], config.get("env_kwargs"))
    model_path = Path(run_dir) / "model.zip"
    if not model_path.is_file():
        checkpoint = Path(run_dir) / "checkpoint.zip"
        if checkpoint.is_file():
            raise ValueError(
                f"{run_dir}: no model.zip here: the run stopped before its end; give its last checkpoint instead, "
                f"{checkpoint}, or finish the run first: avq train --resume {run_dir}"
            )
        raise ValueError(
            f"{run_dir}: no model.zip here: the run stopped before its first checkpoint; "
            f"run it again from the start: avq train --resume {run_dir}"
        )
    return load(model_path, env=given), config["agent"]


def _env_like(env: str, recorded: str | None, make_args: dict[str, Any] | None) -> gym.Env:
    """The environment of ``env``, with the ``gymnasium.make`` arguments ``make_args`` recorded with ``recorded``
    where both name the same id (with or without a module)."""
    same = recorded is not None and split_env_id(env)[1] == split_env_id(recorded)[1]
    return make_env(env, make_args if same else None)


def evaluate_run(
    run_dir: str | os.PathLike,
    episodes: int = 10,
    seed: int | None = 0,
    max_steps: int = 100_000,
    progress: bool = False,
    env: str | None = None,
) -> dict[str, Any]:
    """Load a model and evaluate its greedy policy (and, on a maze, from every start).

    ``run_dir`` is a run directory of :func:`train` (its ``model.zip``, on the environment
    its ``config.yml`` names) or a model file written by ``agent.save`` (on the environment
    the file records), such as those ``avq reproduce`` writes into ``models/``, or a stopped run's
    ``checkpoint.zip``. Episodes are cut at ``max_steps`` steps (:func:`avq.evaluation.evaluate_policy`;
    ``capped`` counts them). The report names the agent (``agent``: its name in ``avq.make_agent``, or its
    class for a file that does not record one) and its ``class``. ``env``: as :func:`load_run`'s.
    """
    from avq.evaluation import evaluate_policy

    model, name = load_run(run_dir, env)
    spec = model.env.spec
    assert spec is not None  # (made from its id: by make_env, or by load from the id the file records)
    made = gym.make(spec)  # (an environment of the evaluation's own, like the agent's)
    result = evaluate_policy(
        model, made, n_eval_episodes=episodes, seed=seed, max_steps=max_steps, progress_bar=progress
    )
    report: dict[str, Any] = {
        "run": str(run_dir),
        "env": spec.id,
        "agent": name,
        "class": type(model).__name__,
        "n_cells": int(model.n_cells),
        "size_unit": model.size_unit,
        **{
            k: result[k]
            for k in ("episodes", "mean_return", "std_return", "mean_steps", "success_rate", "capped", "max_steps")
        },
    }
    if hasattr(made.unwrapped, "layout"):
        maze = evaluate_maze(model, gym.make(spec))  # (a second env like the first)
        report["maze_success_rate"] = maze["success_rate"]
        report["maze_path_ratio"] = maze["path_ratio"]
    return report
