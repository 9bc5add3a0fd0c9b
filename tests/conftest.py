"""Shared test helpers: a scripted environment whose every step is written by hand."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces


class ScriptedEnv(gym.Env):
    """Plays back hand-written episodes, whatever the agent does, and logs its actions.

    ``episodes`` is a list of episodes; each is ``(start, steps)`` with ``start`` the
    first observation and ``steps`` a list of ``(obs, reward, terminated, truncated,
    collision)``. Episodes repeat cyclically.
    """

    def __init__(self, episodes: Sequence[tuple[Sequence[float], Sequence[tuple]]], n_actions: int = 2,
                 low: float = -10.0, high: float = 10.0, dims: int = 2) -> None:
        self.episodes = episodes
        self.observation_space = spaces.Box(low, high, shape=(dims,), dtype=np.float64)
        self.action_space = spaces.Discrete(n_actions)
        self.actions: list[list[int]] = []
        self._ep = -1
        self._t = 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._ep += 1
        self._t = 0
        self.actions.append([])
        start, _ = self.episodes[self._ep % len(self.episodes)]
        return np.asarray(start, dtype=np.float64), {}

    def step(self, action):
        self.actions[-1].append(int(action))
        _, steps = self.episodes[self._ep % len(self.episodes)]
        obs, r, term, trunc, collision = steps[self._t]
        self._t += 1
        return np.asarray(obs, dtype=np.float64), float(r), term, trunc, {"collision": collision}


@pytest.fixture
def scripted():
    return ScriptedEnv
