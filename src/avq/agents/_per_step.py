"""What the agents that decide at every primitive step share (``tabular``, ``grid``, ``tiles``, ``tabular-ps``,
the action codebooks): the step loop that runs them from Python, and one ε-greedy decision."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from avq.agents._td import decide
from avq.agents.base import BaseAgent

__all__ = ["PerStepAgent"]


class PerStepAgent(BaseAgent):
    """A :class:`~avq.agents.BaseAgent` that takes one decision per primitive step."""

    epsilon: float  # the exploration rate of :meth:`_decide`
    _ep_steps: int  # the steps and the return of the episode so far
    _ep_return: float

    def _sarsa_steps(
        self,
        max_steps: int,
        s: Any,
        a: int,
        update: Callable[[Any, int, float, Any, bool], tuple],
        env_actions: Sequence[Any] | np.ndarray | None = None,
    ) -> tuple[Any, int, int, bool]:
        """The primitive steps of an agent that decides at every step (``tabular``, ``grid``, the tile coders).

        Steps the environment with action ``a`` (sent as ``env_actions[a]`` if given) at most
        ``max_steps`` times, refusing a reward or observation that is not finite, and adds the
        rewards to ``_ep_return``; ``update(s, a, r, obs, terminated)`` learns the step and returns the
        next ``(s, a)``. Returns ``(s, a, steps, episode ended)``; ``_ep_steps`` counts the steps.
        """
        env = self.env
        n = 0
        ended = False
        while n < max_steps:
            obs, r, terminated, truncated, _ = env.step(a if env_actions is None else env_actions[a])
            n += 1
            self._check_finite(obs, r, self._ep_steps + n)
            r = float(r)
            self._ep_return += r
            s, a = update(s, a, r, obs, bool(terminated))
            if terminated or truncated:
                ended = True
                break
        self._ep_steps += n
        return s, a, n, ended

    def _decide(self, values: np.ndarray) -> int:
        """ε-greedy over one profile of action values (:func:`avq.agents._td.epsilon_greedy`), drawn
        from the agent's stream."""
        self._draws.reserve()
        return int(decide(self._draws.src, values.reshape(1, -1), 0, self.epsilon))
