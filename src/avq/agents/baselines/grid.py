"""Sarsa(λ) on a fixed uniform grid over a Box observation space (a baseline for AVQ)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import check_int_or_ints, check_per_dimension, check_sarsa_params
from avq.agents._spaces import check_box_discrete, normalize_obs_bounds, resolve_bounds
from avq.agents.baselines.table import TableSarsa

__all__ = ["GridSarsa"]

#: Largest table GridSarsa preallocates (rows); 10^7 rows of 4 actions take 320 MB for values alone.
_MAX_BINS = 10_000_000


def bin_coordinates(x: np.ndarray, low: np.ndarray, bins_per_unit: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """The bin of each dimension of ``x`` (rows of a batch ``(b, n)`` or one ``(n,)``).

    Bin ``k`` of dimension ``d`` is ``[low_d + k w_d, low_d + (k + 1) w_d)`` with
    ``w_d = (high_d - low_d) / bins_d`` (``bins_per_unit = 1 / w``); the last bin also
    holds ``high_d``. Values outside the bounds fall in the edge bins.
    """
    k = np.floor((x - low) * bins_per_unit).astype(np.int64)
    return np.clip(k, 0, bins - 1)


def uniform_grid(space, obs_bounds, bins) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A uniform grid over the bounds of a 1-D ``Box`` space (``obs_bounds`` override them):
    ``(low, high, bins per dimension, bins per unit, strides)``, the strides of the flat C-order index."""
    low, high = resolve_bounds(space, obs_bounds)
    n = low.shape[0]
    per_dim = np.full(n, check_per_dimension("bins", bins, n), dtype=np.int64)
    strides = np.array([math.prod(per_dim[d + 1 :].tolist()) for d in range(n)], dtype=np.int64)
    return low, high, per_dim, per_dim / (high - low), strides


class GridSarsa(TableSarsa):
    """Sarsa(λ) on a fixed uniform discretization of a ``Box`` observation space.

    Every dimension is cut into equal bins between its bounds (the space's, or
    ``obs_bounds``); the cell of an observation is its bin in every dimension, and
    the agent takes one ε-greedy decision per primitive step, as tabular Sarsa(λ)
    does on the cells. This is the fixed-resolution baseline AVQ is compared with.

    Args:
        env: A Gymnasium environment (or registered id) with a 1-D ``Box`` observation
            space and ``Discrete`` actions.
        bins: Bins per dimension: an int, or one int per dimension.
        obs_bounds: None to use the space's bounds, or one entry per dimension:
            ``(low, high)``, or None to keep the space's bounds for that dimension.
            Every dimension must end up bounded (CartPole's velocities are not).
            Observations outside the bounds fall in the edge bins.
        alpha: Step size, in (0, 1].
        lam: Trace decay λ, in [0, 1].
        gamma: Discount γ, in [0, 1].
        epsilon: Exploration rate, in [0, 1].
        q_init: Initial action value of every cell.
        traces: ``"replacing"`` or ``"accumulating"``.
        seed: Seed of every random choice the agent makes and of the env's first reset.

    Attributes:
        q_: ``(prod(bins), m)`` action values, row = flat bin index (C order, see
            :meth:`cells`); bins never visited hold ``q_init``.
        visited_: Flat indices of the bins visited so far, in the order first visited.
        n_cells: Number of distinct bins visited so far.

    The table is preallocated with ``prod(bins)`` rows; internally rows are handed to
    bins in the order they are first visited, so that each update touches only the
    visited rows (the rest have zero traces).
    """

    def __init__(
        self,
        env: gym.Env | str,
        *,
        bins: int | Sequence[int] = 10,
        obs_bounds: Sequence[tuple[float, float] | None] | None = None,
        alpha: float = 0.5,
        lam: float = 0.7,
        gamma: float = 1.0,
        epsilon: float = 0.1,
        q_init: float = 0.0,
        traces: str = "replacing",
        seed: int | None = None,
    ) -> None:
        check_sarsa_params(self, alpha, lam, gamma, epsilon, q_init, traces)
        self.bins = check_int_or_ints("bins", bins)
        self.obs_bounds = normalize_obs_bounds(obs_bounds)
        super().__init__(env, seed)
        self._low, self._high, self._bins, self._bins_per_unit, self._strides = uniform_grid(
            self.env.observation_space, self.obs_bounds, self.bins
        )
        self._n_bins = math.prod(self._bins.tolist())
        if self._n_bins > _MAX_BINS:
            raise ValueError(
                f"bins gives {self._n_bins} cells, more than a preallocated table should hold ({_MAX_BINS}); "
                "use fewer bins or the 'tiles' agent"
            )
        self._low_list = self._low.tolist()
        self._per_dim = list(
            zip(self._low_list, self._bins_per_unit.tolist(), self._bins.tolist(), self._strides.tolist())
        )

    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        check_box_discrete("GridSarsa", obs_space, act_space, "it is a table already")

    # -- learned state ------------------------------------------------------------------
    @property
    def q_(self) -> np.ndarray:
        out = np.full((self._n_bins, self.n_actions), self.q_init)
        if self._is_setup:
            out[self._bin_of_row[: self._n]] = self._q[: self._n]
        return out

    @property
    def visited_(self) -> np.ndarray:
        return self._bin_of_row[: self._n].copy() if self._is_setup else np.zeros(0, dtype=np.int64)

    def cells(self, observations: np.ndarray) -> np.ndarray:
        """The flat bin index (row of :attr:`q_`) of each observation of a batch ``(b, n)``.

        The flat index of bins ``(k_0, ..., k_{n-1})`` is C order:
        ``k_0 * bins_1 * ... * bins_{n-1} + ... + k_{n-1}``.
        """
        x = np.asarray(observations, dtype=np.float64).reshape(-1, self._low.shape[0])
        return bin_coordinates(x, self._low, self._bins_per_unit, self._bins) @ self._strides

    def _setup(self) -> None:
        self._make_table(self._n_bins)
        self._row_of_bin = np.full(self._n_bins, -1, dtype=np.int64)
        self._bin_of_row = np.zeros(self._n_bins, dtype=np.int64)

    def _row(self, obs: Any) -> int:
        """The table row of ``obs``'s bin, handing out the next row on a first visit."""
        xs = np.asarray(obs, dtype=np.float64).tolist()
        if not isinstance(xs, list) or len(xs) != len(self._low_list):
            raise ValueError(f"observation has shape {np.shape(obs)}; the space says {self._low.shape}")
        # bin_coordinates in plain Python (the same float operations, faster for one observation).
        k = 0
        for v, (lo, u, b, stride) in zip(xs, self._per_dim):
            k += min(max(math.floor((v - lo) * u), 0), b - 1) * stride
        row = int(self._row_of_bin[k])
        if row < 0:
            row = self._n
            self._row_of_bin[k] = row
            self._bin_of_row[row] = k
            self._n += 1
            self._ep_new += 1
        return row

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        rows = self._row_of_bin[self.cells(obs)]
        out = np.zeros(len(obs), dtype=np.int64)  # an unvisited bin: all q_init, lowest index
        seen = rows >= 0
        out[seen] = self._q[rows[seen]].argmax(axis=1)
        return out

    # -- saving ---------------------------------------------------------------------------------
    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        arrays["visited"] = self.visited_
        arrays["q"] = self._q[: self._n].copy()
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        super()._load_state_dict(meta, arrays)
        visited, q = arrays["visited"], arrays["q"]
        n = len(visited)
        if visited.ndim != 1 or q.shape != (n, self.n_actions) or len(set(visited.tolist())) != n:
            raise ValueError(f"array shapes visited {visited.shape}, q {q.shape} do not fit {self.n_actions} actions")
        if n and (visited.min() < 0 or visited.max() >= self._n_bins):
            raise ValueError(f"visited bins must lie in [0, {self._n_bins})")
        self._bin_of_row[:n] = visited
        self._row_of_bin[visited] = np.arange(n)
        self._q[:n] = q
        self._n = n
