"""Agents by name: ``make_agent("avq-paper", env)``.

Each entry is a class and the defaults that define the name. The defaults of
``avq-paper`` were chosen by the sweep in ``scripts/sweep_paper_defaults.py``
(see docs/RESULTS.md, "How the defaults were chosen"; the raw results are in
docs/data/sweep-paper-defaults.csv).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from avq.agents.avq_sarsa import AVQSarsa
from avq.agents.base import BaseAgent
from avq.agents.grid import GridSarsa
from avq.agents.tabular import TabularSarsa
from avq.agents.tiles import TileSarsa

__all__ = ["AGENTS", "make_agent"]

#: name -> (class, default hyper-parameters)
AGENTS: dict[str, tuple[type[BaseAgent], dict[str, Any]]] = {
    # The paper's rules exactly: collision trigger only, plain Euclidean metric
    # (scale 1, d_min in the environment's units), merge after every trial.
    "avq-paper": (
        AVQSarsa,
        dict(alpha=0.5, lam=0.7, gamma=1.0, epsilon=0.05, d_min=1.0, rho=5.0, chi=-50.0,
             q_init=5.0, traces="replacing", merge_every=1, value_trigger=None, scale=1.0),
    ),
    "tabular": (
        TabularSarsa,
        dict(alpha=0.1, lam=0.7, gamma=1.0, epsilon=0.1, q_init=0.0, traces="replacing"),
    ),
    "grid": (
        GridSarsa,
        dict(bins=10, obs_bounds=None, alpha=0.2, lam=0.9, gamma=1.0, epsilon=0.0, q_init=0.0,
             traces="replacing"),
    ),
    "tiles": (
        TileSarsa,
        dict(n_tilings=8, tiles_per_dim=8, iht_size=4096, obs_bounds=None, alpha=0.5, lam=0.9, gamma=1.0,
             epsilon=0.0, q_init=0.0, traces="replacing"),
    ),
}


def make_agent(name: str, env: gym.Env | str, seed: int | None = None, **overrides: Any) -> BaseAgent:
    """Create the agent registered as ``name`` with its defaults, updated by ``overrides``.

    Raises:
        ValueError: unknown name, or an override that is not a parameter of the agent.
    """
    if name not in AGENTS:
        raise ValueError(f"unknown agent {name!r}; known agents: {', '.join(sorted(AGENTS))}")
    cls, defaults = AGENTS[name]
    valid = set(cls._param_names()) - {"seed"}
    unknown = sorted(set(overrides) - valid)
    if unknown:
        raise ValueError(
            f"unknown parameter {unknown[0]!r} for agent {name!r}; its parameters: {', '.join(sorted(valid))}"
        )
    return cls(env, **{**defaults, **overrides, "seed": seed})
