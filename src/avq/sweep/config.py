"""A sweep's configuration: the checked YAML description, its grid of configurations and their labels."""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from avq._io import read_yaml

__all__ = ["SweepConfig", "read_sweep_config", "spawn_seeds", "METRICS"]

#: Final metrics of a trial, in ``results.csv`` order, and whether higher is better.
METRICS = {
    "final_return": True,
    "eval_return": True,
    "success_rate": True,
    "path_ratio": False,
    "n_cells": False,
    "env_steps": False,
    "episodes": True,
    "wall_s": False,
}
_KEYS = {
    "env",
    "env_kwargs",
    "agents",
    "grid",
    "params",
    "seeds",
    "root_seed",
    "episodes",
    "timesteps",
    "eval_episodes",
    "metric",
    "save_models",
}
_ENV_PREFIX = "env_kwargs."


@dataclass(frozen=True)
class SweepConfig:
    """A checked sweep description (see the module's docstring for the keys)."""

    env: str
    agents: tuple[str, ...]
    seeds: tuple[int, ...]
    episodes: int | None = None
    timesteps: int | None = None
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list[Any]] = field(default_factory=dict)
    params: dict[str, Any] = field(default_factory=dict)
    root_seed: int = 0
    eval_episodes: int = 10
    metric: str = "final_return"
    save_models: bool = True

    def as_dict(self) -> dict[str, Any]:
        return {
            "env": self.env,
            "env_kwargs": self.env_kwargs,
            "agents": list(self.agents),
            "grid": self.grid,
            "params": self.params,
            "seeds": list(self.seeds),
            "root_seed": self.root_seed,
            **({"episodes": self.episodes} if self.episodes is not None else {"timesteps": self.timesteps}),
            "eval_episodes": self.eval_episodes,
            "metric": self.metric,
            "save_models": self.save_models,
        }


def _is_int(value: Any, low: int) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and bool(value >= low)


def read_sweep_config(source: str | os.PathLike | dict[str, Any]) -> SweepConfig:
    """Read and check a sweep description; a ``ValueError`` names the offending key."""
    from avq.agents.registry import AGENTS

    where = "sweep config"
    if isinstance(source, dict):
        raw = dict(source)
    else:
        where = str(source)
        raw = read_yaml(source, where)
        if not isinstance(raw, dict):
            raise ValueError(f"{source} must be a mapping of keys to values")

    def bad(key: str, why: str) -> ValueError:
        return ValueError(f"{where}: {key!r} {why}")

    unknown = sorted(set(raw) - _KEYS)
    if unknown:
        raise bad(unknown[0], f"is not a sweep key; known keys: {', '.join(sorted(_KEYS))}")
    if not isinstance(raw.get("env"), str) or not raw["env"]:
        raise bad("env", "is required: a registered Gymnasium id such as avq/GridMaze-v0")
    agents = raw.get("agents")
    if isinstance(agents, str):
        agents = [agents]
    if not isinstance(agents, list) or not agents or not all(isinstance(a, str) for a in agents):
        raise bad("agents", "must be a non-empty list of agent names")
    for name in agents:
        if name not in AGENTS:
            raise bad("agents", f"names an unknown agent {name!r}; known agents: {', '.join(sorted(AGENTS))}")
    for key in ("env_kwargs", "grid", "params"):
        if raw.get(key) is not None and not isinstance(raw[key], dict):
            raise bad(key, "must be a mapping")
    grid = {str(k): v for k, v in (raw.get("grid") or {}).items()}
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise bad(f"grid.{key}", "must be a non-empty list of values")
        if key in ("seed",):
            raise bad(f"grid.{key}", "cannot be swept; seeds come from 'seeds'")
    root_seed = raw.get("root_seed", 0)
    if not _is_int(root_seed, 0):
        raise bad("root_seed", f"must be an integer >= 0, not {root_seed!r}")
    seeds = raw.get("seeds", 1)
    if _is_int(seeds, 1):
        seed_list = spawn_seeds(int(root_seed), int(seeds))
    elif isinstance(seeds, list) and seeds and all(_is_int(s, 0) for s in seeds):
        if len(set(seeds)) != len(seeds):
            raise bad("seeds", "lists a seed twice")
        seed_list = tuple(int(s) for s in seeds)
    else:
        raise bad("seeds", f"must be a count >= 1 or a non-empty list of integers >= 0, not {seeds!r}")
    episodes, timesteps = raw.get("episodes"), raw.get("timesteps")
    if (episodes is None) == (timesteps is None):
        raise bad("episodes", "or 'timesteps' is required, and not both")
    for key, value in (("episodes", episodes), ("timesteps", timesteps)):
        if value is not None and not _is_int(value, 1):
            raise bad(key, f"must be an integer >= 1, not {value!r}")
    eval_episodes = raw.get("eval_episodes", 10)
    if not _is_int(eval_episodes, 0):
        raise bad("eval_episodes", f"must be an integer >= 0, not {eval_episodes!r}")
    metric = raw.get("metric", "final_return")
    if metric not in METRICS:
        raise bad("metric", f"must be one of {', '.join(METRICS)}, not {metric!r}")
    save_models = raw.get("save_models", True)
    if not isinstance(save_models, bool):
        raise bad("save_models", f"must be true or false, not {save_models!r}")
    params = dict(raw.get("params") or {})
    if "seed" in params:
        raise bad("params", "cannot set seed; seeds come from 'seeds'")
    config = SweepConfig(
        env=raw["env"],
        agents=tuple(agents),
        seeds=seed_list,
        episodes=episodes,
        timesteps=timesteps,
        env_kwargs=dict(raw.get("env_kwargs") or {}),
        grid=grid,
        params=params,
        root_seed=int(root_seed),
        eval_episodes=int(eval_episodes),
        metric=metric,
        save_models=save_models,
    )
    _check_configurations(config, where)
    return config


def spawn_seeds(root_seed: int, n: int) -> tuple[int, ...]:
    """``n`` seeds, the children of ``numpy.random.SeedSequence(root_seed)``: a sweep's (and a tuning's) seeds."""
    return tuple(int(c.generate_state(1)[0]) for c in np.random.SeedSequence(root_seed).spawn(n))


def _configurations(config: SweepConfig) -> list[tuple[str, dict[str, Any]]]:
    """Every (agent, grid point) in a fixed order: agents, then the grid's product in key order."""
    keys = list(config.grid)
    points = [dict(zip(keys, values)) for values in itertools.product(*(config.grid[k] for k in keys))]
    return [(agent, point) for agent in config.agents for point in points]


def _split(point: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A grid point as (agent parameters, environment arguments)."""
    params = {k: v for k, v in point.items() if not k.startswith(_ENV_PREFIX)}
    env_kwargs = {k[len(_ENV_PREFIX) :]: v for k, v in point.items() if k.startswith(_ENV_PREFIX)}
    return params, env_kwargs


def _check_configurations(config: SweepConfig, where: str) -> None:
    """Make each configuration's agent once (on the base environment), so bad values fail before any trial."""
    from avq.agents.registry import make_agent
    from avq.runs import make_env

    try:
        env = make_env(config.env, config.env_kwargs)
    except ValueError as exc:
        raise ValueError(f"{where}: 'env': {exc}") from None
    env_keys = {k: v[0] for k, v in config.grid.items() if k.startswith(_ENV_PREFIX)}
    if env_keys:  # the names of varied env arguments, with their first values (later ones fail as trials)
        try:
            make_env(config.env, {**config.env_kwargs, **_split(env_keys)[1]})
        except ValueError as exc:
            keys = ", ".join(f"grid.{k}" for k in env_keys)
            raise ValueError(f"{where}: {keys}: {exc}") from None
    for agent, point in _configurations(config):
        params, _ = _split(point)
        try:
            make_agent(agent, env, seed=0, **{**config.params, **params})
        except (TypeError, ValueError) as exc:
            keys = ", ".join(f"grid.{k}" for k in params) or "params"
            raise ValueError(
                f"{where}: agent {agent} with {_label(params) or 'its defaults'} ({keys}): {exc}"
            ) from None


def _label(point: dict[str, Any]) -> str:
    return " ".join(f"{k}={v}" for k, v in point.items())
