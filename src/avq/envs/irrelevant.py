"""Observations that carry more than the task needs: ``k`` dimensions appended to any task's vector of
observations, noise or a slow drift, which a learner must learn to ignore."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import check_choice, check_int, check_range

__all__ = ["IrrelevantDims"]


class IrrelevantDims(gym.ObservationWrapper[np.ndarray, Any, np.ndarray], gym.utils.RecordConstructorArgs):
    """``k`` irrelevant dimensions, each in [0, 1], appended to the observation of a task whose observations
    are a ``Box`` of shape ``(n,)``.

    The new observation space is a ``Box`` of shape ``(n + k,)``: the task's bounds, then 0 and 1 for each new
    dimension (the task's dtype, or float64 for an integer one). The task is unchanged; only what the agent
    sees grows. ``k = 0`` adds nothing.

    Args:
        env: The task.
        k: Dimensions to append, an integer >= 0.
        kind: ``"noise"``: every new dimension uniform in [0, 1], drawn again at every reset and step;
            ``"walk"``: a slow random walk, uniform in [0, 1] at a reset, then at every step moved by a
            uniform amount in ``[-walk_step, walk_step]`` and reflected at 0 and 1 (so it moves by at most
            ``walk_step``).
        walk_step: The walk's largest move, in (0, 1].

    The draws come from the wrapper's own generator, not the task's: ``reset(seed=s)`` seeds it (from a child
    of ``s``'s ``SeedSequence``, so that its stream differs from the task's), and the same seed gives the
    same observations. Without any seed it is seeded from fresh entropy at the first reset.

    Raises:
        ValueError: ``k``, ``kind`` or ``walk_step`` is out of range, or the task's observations are not a
            ``Box`` of shape ``(n,)``.
    """

    def __init__(self, env: gym.Env, k: int, kind: str = "noise", walk_step: float = 0.01) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, k=k, kind=kind, walk_step=walk_step)
        super().__init__(env)
        self.k = check_int("k", k, 0)
        self.kind = check_choice("kind", kind, ("noise", "walk"))
        self.walk_step = check_range("walk_step", walk_step, 0.0, 1.0, low_open=True)
        inner = env.observation_space
        if not isinstance(inner, spaces.Box) or len(inner.shape) != 1:
            raise ValueError(
                f"IrrelevantDims needs a task whose observation space is a Box of shape (n,), not {inner}; "
                "flatten it first (gymnasium.wrappers.FlattenObservation) or wrap another task"
            )
        dtype = inner.dtype if np.issubdtype(inner.dtype, np.floating) else np.dtype(np.float64)
        self.observation_space = spaces.Box(
            low=np.concatenate((inner.low.astype(dtype), np.zeros(self.k, dtype))),
            high=np.concatenate((inner.high.astype(dtype), np.ones(self.k, dtype))),
            dtype=dtype,
        )
        self._n = inner.shape[0]
        self._extra = np.zeros(self.k, dtype=np.float64)
        self._rng: np.random.Generator | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Reset the task (with ``seed`` and ``options``), seed the wrapper's generator with ``seed`` if given,
        and draw the new dimensions afresh."""
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(1)[0])
        self._extra[:] = self._rng.random(self.k)
        return super().reset(seed=seed, options=options)

    def step(self, action: Any) -> tuple[np.ndarray, Any, bool, bool, dict]:
        """Step the task and move the new dimensions (drawn again, or one step of the walk)."""
        if self._rng is None:  # (a step before any reset, if the task allows it)
            self._rng = np.random.default_rng()
        rng = self._rng
        if self.kind == "noise":
            self._extra[:] = rng.random(self.k)
        else:
            x = np.abs(self._extra + rng.uniform(-self.walk_step, self.walk_step, self.k))
            self._extra[:] = 1.0 - np.abs(1.0 - x)  # (reflected at 0, then at 1: |move| <= walk_step <= 1)
        return super().step(action)

    def observation(self, observation: np.ndarray) -> np.ndarray:
        """The task's observation followed by the ``k`` new dimensions."""
        out = np.empty(self._n + self.k, dtype=self.observation_space.dtype)
        out[: self._n] = observation
        out[self._n :] = self._extra
        return out
