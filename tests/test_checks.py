"""The conformance check, run over every agent, and shown to catch broken agents."""

from __future__ import annotations

import numpy as np
import pytest

from avq import AGENTS, TabularSarsa
from avq.checks import CHECKS, check_agent

#: Every agent for Discrete actions (those for Box actions are checked in test_actions.py).
DISCRETE = sorted(n for n in AGENTS if n not in ("avq-actions", "uniform-actions"))


@pytest.mark.parametrize("name", DISCRETE)
def test_every_agent_passes_on_the_maze(name):
    assert check_agent(name, "avq/GridMaze-v0", episodes=4) == list(CHECKS)


@pytest.mark.parametrize("name", DISCRETE)
def test_every_agent_passes_on_a_gymnasium_task(name):
    assert check_agent(name, "MountainCar-v0", episodes=3) == list(CHECKS)


def test_the_generic_avq_path_passes_on_the_maze():
    check_agent("avq-paper", "avq/GridMaze-v0", params={"fused": False})


class ForgetsValues(TabularSarsa):
    """Saves everything but its values."""

    def _state_dict(self):
        meta, arrays = super()._state_dict()
        arrays["q"] = np.zeros_like(arrays["q"])
        return meta, arrays


class ForgetsWhereItStopped(TabularSarsa):
    """Starts a fresh episode on every call to learn."""

    def learn(self, *args, **kwargs):
        self._in_episode = False
        return super().learn(*args, **kwargs)


class AcceptsAnyAlpha(TabularSarsa):
    """Stores alpha without checking it."""

    def __init__(self, env, alpha=0.1, seed=None):
        super().__init__(env, seed=seed)
        self.alpha = alpha


@pytest.mark.parametrize(
    ("cls", "check"),
    [
        (ForgetsValues, "save_load"),
        (ForgetsWhereItStopped, "additive_learn"),
        (AcceptsAnyAlpha, "parameters"),
    ],
)
def test_the_check_catches_broken_agents(cls, check):
    with pytest.raises(AssertionError, match=f"failed the '{check}' check"):
        check_agent(cls, "avq/GridMaze-v0")


def test_unknown_agent_name():
    with pytest.raises(ValueError, match="unknown agent 'nope'"):
        check_agent("nope")
