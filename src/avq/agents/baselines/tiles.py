"""Linear Sarsa(λ) with tile coding (Sutton & Barto 2018, §9.5.4 and §12.7): a baseline for AVQ.

:class:`TileCodedSarsa` is what every tile-coded agent shares (the tile coding, the weights and their
traces, the step loop, saving); :class:`TileSarsa` is the baseline, and
:class:`avq.agents.actions.ActionCodebookSarsa` the same learner over an adaptive codebook of actions.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import SarsaSettings, check_int, check_int_or_ints, check_per_dimension, check_sarsa_params
from avq.agents._per_step import PerStepAgent
from avq.agents._spaces import check_box_discrete, normalize_obs_bounds, resolve_bounds
from avq.agents._td import sarsa_td_error, tile_step
from avq.agents.base import EpisodeRecord, episode_record
from avq.tilecoding import TileCoder

__all__ = ["TileSarsa", "TileCodedSarsa", "mark_traces"]


def mark_traces(e: np.ndarray, active: np.ndarray, a: int, replacing: bool) -> None:
    """Mark the traces of the active tiles for action ``a``, all but what
    :func:`avq.agents._td.trace_update` marks itself.

    That function marks the trace of one (row, action), ``(active[0], a)``, and then
    updates every row; a tile-coded state has one row per tiling, so the others are
    marked here first.

    Replacing traces: ``e[i, a] = 1`` for every active tile ``i`` (setting
    ``active[0]`` here too is harmless), and the other actions' traces of those
    tiles are cleared, as in Sutton & Barto's replacing-trace Sarsa(λ) for Mountain
    Car. Accumulating traces: ``e[i, a] += 1`` once per occurrence of ``i`` in
    ``active[1:]`` (a tile can occur twice once the coder hashes).
    """
    if replacing:
        e[active] = 0.0
        e[active, a] = 1.0
    else:
        np.add.at(e[:, a], active[1:], 1.0)


class TileCodedSarsa(SarsaSettings, PerStepAgent):
    """What the tile-coded agents share (``TileSarsa``, ``ActionCodebookSarsa``): linear Sarsa(λ) with
    traces on the features, one ε-greedy decision per primitive step, on the states of a ``TileCoder``.

    ``Q(s, a) = sum_i w[i, a]`` over the active tiles ``i`` of ``s``: the weights ``_w`` and traces ``_e``
    are ``(iht_size, columns)``, a column per action; a subclass may use fewer, its *live* actions
    (:meth:`_live_weights`). It says in ``_setup`` how many columns to allocate (:meth:`_setup_tiles`).
    """

    n_tilings: int
    tiles_per_dim: int | list[int]
    iht_size: int
    obs_bounds: list[list[float] | None] | None

    def __init__(
        self,
        env: gym.Env | str,
        seed: int | None,
        n_tilings: int,
        tiles_per_dim: int | Sequence[int],
        iht_size: int,
        obs_bounds: Sequence[tuple[float, float] | None] | None,
    ) -> None:
        """Check and store the tile coding's parameters, make the environment (``BaseAgent``) and resolve
        the bounds that are tiled. A subclass checks its own parameters (and ``check_sarsa_params``) first."""
        self.n_tilings = check_int("n_tilings", n_tilings, 1)
        self.tiles_per_dim = check_int_or_ints("tiles_per_dim", tiles_per_dim)
        self.iht_size = check_int("iht_size", iht_size, 1)
        self.obs_bounds = normalize_obs_bounds(obs_bounds)
        super().__init__(env, seed)
        self._low, self._high = resolve_bounds(self.env.observation_space, self.obs_bounds)
        check_per_dimension("tiles_per_dim", self.tiles_per_dim, self._low.shape[0])
        if self.iht_size < self.n_tilings:
            raise ValueError(f"iht_size must be at least n_tilings ({self.n_tilings}), not {self.iht_size}")

    @property
    def tile_coder_(self) -> TileCoder:
        return self._coder

    def _live_weights(self) -> np.ndarray:
        """The columns of ``_w`` of the actions in use (a view): all of them here."""
        return self._w

    def q_values(self, observations: np.ndarray) -> np.ndarray:
        """``Q(s, a)`` of every action in use for each observation of a batch ``(b, n)``: ``(b, m)``.

        A query: tiles never met count with their initial weight and are not added.
        """
        if not self._is_setup:
            raise RuntimeError(f"{type(self).__name__} has not learned yet; call learn() first")
        x = np.asarray(observations, dtype=np.float64).reshape(-1, self._low.shape[0])
        w = self._live_weights()
        out = np.empty((len(x), w.shape[1]))
        w0 = np.full(w.shape[1], self.q_init / self.n_tilings)
        for b, xb in enumerate(x):
            active = self._coder(xb, readonly=True)
            out[b] = np.where(active[:, None] >= 0, w[np.maximum(active, 0)], w0).sum(axis=0)
        return out

    def _setup_tiles(self, columns: int) -> None:
        """The tile coder, the weights (at ``q_init / n_tilings``) and traces of ``columns`` actions, and
        the episode's state."""
        bounds = list(zip(self._low.tolist(), self._high.tolist()))
        self._coder = TileCoder(bounds, self.tiles_per_dim, self.n_tilings, self.iht_size)
        self._w = np.full((self.iht_size, columns), self.q_init / self.n_tilings)
        self._e = np.zeros((self.iht_size, columns))
        self._step_size = self.alpha / self.n_tilings
        self._ep_active = np.zeros(self.n_tilings, dtype=np.int64)
        self._ep_action = 0
        self._ep_steps = 0
        self._ep_return = 0.0

    def _features(self, obs: Any) -> np.ndarray:
        """The active tiles of an observation (tiles met for the first time are added)."""
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != self._low.shape:
            raise ValueError(f"observation has shape {x.shape}; the space says {self._low.shape}")
        return self._coder(x)

    def _values(self, active: np.ndarray) -> np.ndarray:
        """``Q(s, .)`` of the state with these active tiles (one summation order everywhere)."""
        return self._w.take(active, axis=0).sum(axis=0)

    def _sent_actions(self) -> Sequence[Any] | None:
        """What the environment is sent for each action index, or None: the index itself."""
        return None

    # -- the episode loop (Sutton & Barto 2018, §12.7) ------------------------------------
    def _begin_episode(self, obs: np.ndarray) -> None:
        # Rows past n_used have never been marked, so clearing the used ones clears all.
        self._e[: self._coder.n_used] = 0.0
        self._ep_steps = 0
        self._ep_return = 0.0
        self._check_finite(obs, 0.0, 0)
        self._ep_active = self._features(obs)
        self._ep_action = self._decide(self._values(self._ep_active))

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        w, e, coder = self._w, self._e, self._coder
        rows = np.arange(w.shape[0])
        replacing = self.traces == "replacing"
        decay = self.gamma * self.lam

        def update(active: np.ndarray, a: int, r: float, obs: Any, terminated: bool) -> tuple[np.ndarray, int]:
            q_sa = self._values(active)[a]
            if terminated:
                active2, a2 = active, a
                delta = sarsa_td_error(q_sa, r, self.gamma, 0.0, True)
            else:
                active2 = self._features(obs)
                q2 = self._values(active2)
                a2 = self._decide(q2)
                delta = sarsa_td_error(q_sa, r, self.gamma, q2[a2], False)
            mark_traces(e, active, a, replacing)
            # Rows are handed out in order of first use: rows past n_used have zero traces.
            tile_step(w, e, rows, coder.n_used, int(active[0]), a, delta, self._step_size, decay, replacing)
            return active2, a2

        self._ep_active, self._ep_action, n, ended = self._sarsa_steps(
            max_steps, self._ep_active, self._ep_action, update, self._sent_actions()
        )
        return n, ended

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        return self.q_values(obs).argmax(axis=1).astype(np.int64)

    # -- saving ---------------------------------------------------------------------------------
    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        meta["overflows"] = self._coder.overflows
        arrays["weights"] = self._w.copy()
        arrays["tiles"] = self._coder.tiles()
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        super()._load_state_dict(meta, arrays)
        w = arrays["weights"]
        if w.shape != self._w.shape:
            raise ValueError(f"weights of shape {w.shape} do not fit {self._w.shape}")
        self._coder.restore(arrays["tiles"], int(meta["overflows"]))
        self._w[:] = w


class TileSarsa(TileCodedSarsa):
    """Linear Sarsa(λ) on tile-coded features, like Sutton & Barto's Mountain Car agent.

    The observation is tile-coded by a ``TileCoder`` (src/avq/tilecoding.py; ``n_tilings``
    tilings of ``tiles_per_dim`` tiles per dimension, displaced asymmetrically as in
    Sutton's ``tiles3``, indices from an index hash table of ``iht_size``). The value
    of an action is the sum of its weights over the active tiles,
    ``Q(s, a) = sum_i w[i, a]``, and Sarsa(λ) learns the weights with eligibility
    traces on the features, one ε-greedy decision per primitive step.

    Args:
        env: A Gymnasium environment (or registered id) with a 1-D ``Box`` observation
            space and ``Discrete`` actions.
        n_tilings: Number of tilings (active tiles per observation).
        tiles_per_dim: Tiles per dimension across the bounds, an int or one per dimension.
        iht_size: Size of the index hash table = number of weight rows.
        obs_bounds: None to use the space's bounds, or one entry per dimension:
            ``(low, high)``, or None to keep the space's bounds for that dimension.
            Every dimension must end up bounded (CartPole's velocities are not).
        alpha: Total step size, in (0, 1]; each weight moves by ``alpha / n_tilings``
            times the TD error (times its trace), so that one update moves ``Q`` of the
            state by about ``alpha`` of the error, as in the book.
        lam: Trace decay λ, in [0, 1].
        gamma: Discount γ, in [0, 1].
        epsilon: Exploration rate, in [0, 1].
        q_init: Initial value of every ``Q(s, a)``: weights start at ``q_init / n_tilings``.
        traces: ``"replacing"`` or ``"accumulating"`` traces on the features.
        seed: Seed of every random choice the agent makes and of the env's first reset.

    Attributes:
        weights_: ``(iht_size, m)`` weights.
        tile_coder_: The ``TileCoder`` (src/avq/tilecoding.py) with its index hash table.
        n_cells: Tiles in use in the index hash table.

    Episode records count, in ``appends``, the tiles first met in the episode and,
    in ``refused``, the tile lookups that overflowed the full table and were hashed.
    """

    size_unit = "tiles"

    def __init__(
        self,
        env: gym.Env | str,
        *,
        n_tilings: int = 8,
        tiles_per_dim: int | Sequence[int] = 8,
        iht_size: int = 4096,
        obs_bounds: Sequence[tuple[float, float] | None] | None = None,
        alpha: float = 0.5,
        lam: float = 0.9,
        gamma: float = 1.0,
        epsilon: float = 0.05,
        q_init: float = 0.0,
        traces: str = "replacing",
        seed: int | None = None,
    ) -> None:
        check_sarsa_params(self, alpha, lam, gamma, epsilon, q_init, traces)
        super().__init__(env, seed, n_tilings, tiles_per_dim, iht_size, obs_bounds)

    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        check_box_discrete("TileSarsa", obs_space, act_space, "there is nothing to tile-code")

    # -- learned state ------------------------------------------------------------------
    @property
    def n_cells(self) -> int:
        return self._coder.n_used if self._is_setup else 0

    @property
    def weights_(self) -> np.ndarray:
        return self._w.copy()

    def _setup(self) -> None:
        self._setup_tiles(self.n_actions)
        self._ep_used0 = 0
        self._ep_overflows0 = 0

    # -- the episode loop: as TileCodedSarsa, counting the tiles the episode adds --------
    def _begin_episode(self, obs: np.ndarray) -> None:
        self._ep_used0 = self._coder.n_used
        self._ep_overflows0 = self._coder.overflows
        super()._begin_episode(obs)

    def _end_episode(self) -> EpisodeRecord:
        coder = self._coder
        return episode_record(
            self._ep_steps,
            self._ep_return,
            coder.n_used,
            coder.n_used - self._ep_used0,
            refused=coder.overflows - self._ep_overflows0,
        )
