"""What the agents of :class:`avq.agents._spaces.ScaledMetric` count of their observations: the spread of the first
``scale_warmup`` (``scale="auto"``'s estimates) and, for the tests of :mod:`avq.agents._noise`, a log of them with
their actions and rewards, kept longer while a drifting dimension waits to be judged; and how a saved agent keeps
both."""

from __future__ import annotations

from typing import Any

import numpy as np

from avq.agents._noise import drift_dims, drift_matters, noise_dims

__all__ = ["RunningSpread", "scale_state", "load_scale_state"]


class RunningSpread:
    """The mean and standard deviation per dimension of the first ``limit`` observations, kept as they come
    (Welford's algorithm: the same numbers as ``numpy.std`` up to rounding), and with ``log`` the observations
    themselves, first the same ``limit`` of them, more after :meth:`extend_log`.

    Attributes:
        count: The observations counted so far (at most ``limit``).
        mean: ``(n,)`` their mean.
        m2: ``(n,)`` the sum of squared deviations from the mean.
        logged: The observations in the log (at most ``log_limit``; 0 without ``log``).
    """

    def __init__(self, n: int, limit: int, log: bool = False) -> None:
        self.limit = limit
        self.count = 0
        self.mean = np.zeros(n)
        self.m2 = np.zeros(n)
        self.log_limit = limit if log else 0
        self.logged = 0
        #: With ``log``, the observations logged (the first :attr:`logged` rows), whether each came one step after
        #: the one before it in the same episode, and the action and reward of that step (-1 and 0 for the first
        #: of an episode): for the tests of avq.agents._noise (:meth:`noise`, :meth:`drift_matters`).
        self.obs = np.zeros((limit, n)) if log else None
        self.follows = np.zeros(self.log_limit, dtype=bool)
        self.actions = np.full(self.log_limit, -1, dtype=np.int64)
        self.rewards = np.zeros(self.log_limit)

    @property
    def full(self) -> bool:
        """True once ``limit`` observations were counted: later ones are not (but may still be logged)."""
        return self.count >= self.limit

    @property
    def log_full(self) -> bool:
        """True once the log holds ``log_limit`` observations."""
        return self.logged >= self.log_limit

    @property
    def done(self) -> bool:
        """True once neither the spread nor the log takes more observations."""
        return self.full and self.log_full

    def extend_log(self, rows: int) -> None:
        """Make room in the log for ``rows`` observations in all (no fewer than it has)."""
        assert self.obs is not None
        rows = max(rows, self.log_limit)
        self.obs = np.concatenate([self.obs, np.zeros((rows - self.log_limit, self.obs.shape[1]))])
        self.follows = np.concatenate([self.follows, np.zeros(rows - self.log_limit, dtype=bool)])
        self.actions = np.concatenate([self.actions, np.full(rows - self.log_limit, -1, dtype=np.int64)])
        self.rewards = np.concatenate([self.rewards, np.zeros(rows - self.log_limit)])
        self.log_limit = rows

    def add(self, x: Any, start: bool = False, action: int = -1, reward: float = 0.0) -> bool:
        """Count and log the observation ``x`` (where there is room), the first of an episode when ``start``, else
        the one that ``action`` led to with ``reward``; return whether later ones are still taken."""
        if self.logged < self.log_limit:
            assert self.obs is not None
            self.obs[self.logged], self.follows[self.logged] = x, not start
            self.actions[self.logged], self.rewards[self.logged] = action, reward
            self.logged += 1
        if self.count < self.limit:
            self.count += 1
            delta = x - self.mean
            self.mean += delta / self.count
            self.m2 += delta * (x - self.mean)
        return not self.done

    def log(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The log so far: observations, whether each follows the one before it, actions and rewards."""
        assert self.obs is not None
        c = self.logged
        return self.obs[:c], self.follows[:c], self.actions[:c], self.rewards[:c]

    def noise(self) -> np.ndarray:
        """:func:`avq.agents._noise.noise_dims` of the observations logged."""
        return noise_dims(*self.log())

    def drift(self, noise: np.ndarray) -> np.ndarray:
        """:func:`avq.agents._noise.drift_dims` of the observations logged, besides the dimensions ``noise``."""
        obs, follows, actions, _ = self.log()
        return drift_dims(obs, follows, actions, noise)

    def drift_matters(self, drift: np.ndarray) -> np.ndarray:
        """:func:`avq.agents._noise.drift_matters` of the observations logged, for the dimensions ``drift``."""
        return drift_matters(*self.log(), drift)

    def std(self) -> np.ndarray:
        """``(n,)`` the standard deviation of the observations counted (ddof 0; zeros before any)."""
        return np.sqrt(self.m2 / max(self.count, 1))


def scale_state(scale: np.ndarray, spread: RunningSpread) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """What a saved agent keeps of its metric: ``(meta, arrays)``, the scale in force and what
    ``scale="auto"`` counted of the observations (mean and m2 as rows), and the observations logged for the noise
    test (as rows, with whether each followed the one before it, the action and the reward as last columns)."""
    arrays = {"scale": scale.copy(), "scale_spread": np.stack([spread.mean, spread.m2])}
    meta: dict[str, Any] = {"scale_count": spread.count}
    if spread.obs is not None:
        arrays["noise_log"] = np.column_stack(spread.log())
        meta.update(log_count=spread.logged, log_limit=spread.log_limit)
    return meta, arrays


def load_scale_state(
    meta: dict[str, Any], arrays: dict[str, np.ndarray], scale: np.ndarray, estimated: np.ndarray, spread: RunningSpread
) -> None:
    """Restore what :func:`scale_state` saved into ``scale`` and ``spread`` (in place). A file from before
    ``scale="auto"`` keeps the scale of the parameters; one from before the longer log, a log as long as the count.

    Raises:
        ValueError: a saved scale that does not fit the parameters' (shape, sign, or a dimension that is
            not estimated but differs), or a spread or log of the wrong shape.
    """
    n = scale.shape[0]
    saved = arrays.get("scale", scale)
    if saved.shape != (n,) or not (saved > 0).all() or not np.array_equal(saved[~estimated], scale[~estimated]):
        raise ValueError(f"array scale {saved.tolist()} does not fit the parameters' scale {scale.tolist()}")
    rows = arrays.get("scale_spread", np.zeros((2, n)))
    if rows.shape != (2, n):
        raise ValueError(f"array scale_spread has shape {rows.shape}; expected (2, {n})")
    spread.count = min(int(meta.get("scale_count", 0)), spread.limit)
    spread.mean[:], spread.m2[:] = rows
    if spread.obs is not None:
        spread.extend_log(int(meta.get("log_limit", spread.limit)))
        logged = min(int(meta.get("log_count", spread.count)), spread.log_limit)
        kept = arrays.get("noise_log", np.zeros((0, n + 3)))
        if kept.shape not in ((logged, n + 1), (logged, n + 3)):  # (n + 1: without actions and rewards)
            raise ValueError(f"array noise_log has shape {kept.shape}; expected ({logged}, {n + 3})")
        spread.logged = logged
        spread.obs[:logged], spread.follows[:logged] = kept[:, :n], kept[:, n] > 0
        if kept.shape[1] == n + 3:
            spread.actions[:logged], spread.rewards[:logged] = kept[:, n + 1], kept[:, n + 2]
    scale[:] = saved
