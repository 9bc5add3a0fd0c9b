"""Potential-based reward shaping: what a user knows of a task (how far its goal is, say) given to any agent as a
reward, without changing which policies are best."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from avq._validate import check_range

__all__ = ["PotentialShaping"]


class PotentialShaping(gym.Wrapper[Any, Any, Any, Any], gym.utils.RecordConstructorArgs):
    """The task's rewards reshaped by a potential over its observations: ``r + gamma * phi(s') - phi(s)``.

    Ng, Harada & Russell (1999): adding the change of a potential ``phi`` to every reward leaves the task's
    optimal policies as they were, whatever ``phi`` is, if ``phi`` counts as 0 once the episode terminates
    (here it does: a step that terminates adds ``-phi(s)``). With ``gamma`` 1 an episode's shaped return is its
    return plus ``phi`` at the last observation if the episode was truncated (0 if it terminated), less ``phi``
    at the first. A potential that rises towards the goal (the negative of a distance to it, say) makes steps
    towards the goal cost less than steps away, which is how an agent is told where the goal is without being
    told how to reach it; an agent whose untried decisions are worth a fixed optimistic value then tries first
    those that lead towards the goal. :meth:`avq.envs.SlabMaze.goal_distance` gives such a potential for the
    slab maze.

    Args:
        env: The task.
        potential: A function of one observation that returns a finite number.
        gamma: The discount the shaping assumes, in (0, 1]: the agent's own ``gamma`` for the optimal policies
            to stay the same (1 for avq's planning agent).

    ``info["unshaped_reward"]`` holds the task's own reward at every step (the innermost shaping's, where shapings
    are stacked); to record the task's returns, wrap the task in ``gymnasium.wrappers.RecordEpisodeStatistics``
    before shaping it. The potential is recorded in the env's spec as given, so a spec with a lambda does not
    serialise to JSON, as with Gymnasium's own wrappers that take functions.

    Raises:
        TypeError: ``potential`` is not callable.
        ValueError: ``gamma`` is out of range; at a reset or step, ``potential`` returns something that is not a
            finite number (the message names the value and the observation).
    """

    def __init__(self, env: gym.Env, potential: Callable[[Any], float], gamma: float = 1.0) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, potential=potential, gamma=gamma)
        super().__init__(env)
        if not callable(potential):
            raise TypeError(
                f"potential must be a function of one observation that returns a number, not {potential!r}; "
                "give, for instance, lambda obs: -maze.goal_distance(obs)"
            )
        self.potential = potential
        self.gamma = check_range("gamma", gamma, 0.0, 1.0, low_open=True)
        self._phi = 0.0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        """Reset the task and note the first observation's potential."""
        obs, info = self.env.reset(seed=seed, options=options)
        self._phi = self._potential_of(obs)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        """Step the task; the reward plus ``gamma`` times the new potential (0 if the episode terminated) less the
        last one."""
        obs, reward, terminated, truncated, info = self.env.step(action)
        phi = 0.0 if terminated else self._potential_of(obs)
        shaped = float(reward) + self.gamma * phi - self._phi
        self._phi = phi
        return obs, shaped, terminated, truncated, {"unshaped_reward": float(reward), **info}  # (the innermost)

    def _potential_of(self, obs: Any) -> float:
        value = self.potential(obs)
        real = np.ndim(value) == 0 and isinstance(value, (int, float, np.integer, np.floating))
        phi = float(value) if real and not isinstance(value, (bool, np.bool_)) else math.nan
        if not math.isfinite(phi):
            raise ValueError(
                f"potential({np.asarray(obs).tolist()!r}) returned {value!r}, not a finite number; "
                "make the potential return a finite number for every observation"
            )
        return phi
