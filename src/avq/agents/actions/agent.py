"""AVQ on the action space: Sarsa(λ) over an adaptive codebook of continuous actions.

The paper's last remark (docs/explanation/paper.md#future-work) proposes vector quantization of the action
space. Here the *states* are tile-coded as in :class:`avq.agents.tiles.TileSarsa`
and the *actions* are a codebook of vectors in the environment's ``Box`` action
space, grown and merged by rules transposed from docs/explanation/paper.md#growing and #merging:

- **Growth** (the analogue of appending a vector): where the policy spends its
  decisions, split. The action chosen greedily most often over the recently
  visited states, ``g``, and its best-valued neighbour ``j`` get a new vector
  between them, ``(y_g + y_j) / 2``, whose value column starts at the mean of
  theirs. Never within ``d_min`` of an existing vector, never beyond
  ``max_actions``.
- **Merging** (docs/explanation/paper.md#merging with states and actions swapped): two action vectors
  that are each other's nearest and whose value columns, over the recently
  visited states, differ by a mean square below ``rho`` become one: vector and
  weights averaged, the later slots move down.

Distances between actions are measured in units of the action range (every
dimension scaled to [0, 1]), so ``d_min`` is a fraction of the range.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import check_bool, check_int, check_range, check_sarsa_params
from avq.agents.actions.codebook import merged_vector, plan_growth, plan_merges, uniform_actions
from avq.agents.base import EpisodeRecord, episode_record
from avq.agents.baselines.tiles import TileCodedSarsa

__all__ = ["ActionCodebookSarsa"]


# -- the agent --------------------------------------------------------------------------------------------


class ActionCodebookSarsa(TileCodedSarsa):
    """Linear Sarsa(λ) on tile-coded states over an adaptive codebook of continuous actions.

    The learner is :class:`avq.agents.TileSarsa`'s: ``Q(s, a) = sum_i w[i, a]``
    over the active tiles of ``s``, Sarsa(λ) with traces on the features, one
    ε-greedy decision per primitive step. Its discrete actions are the vectors of
    an action codebook: at the start a uniform grid of ``init_actions`` values per
    action dimension (low to high); with ``fixed=False``, every ``adapt_every``
    episodes a merge pass and then one growth step (the rules: ``plan_merges``, ``plan_growth``
    and ``merged_vector`` in src/avq/agents/actions/codebook.py, described in its docstring), judged on the
    last ``memory`` visited states. With ``fixed=True`` the grid stays: the uniform
    discretization with the same learner.

    Args:
        env: A Gymnasium environment (or registered id) with a 1-D ``Box`` observation
            space and a bounded ``Box`` action space.
        init_actions: Values per action dimension of the initial uniform grid, >= 1
            (``init_actions ** dims`` vectors; 1 is the centre).
        fixed: Keep the initial grid (no growth, no merging).
        max_actions: Most action vectors at once (the weight table's columns).
        adapt_every: Episodes between adaptation passes (merge pass, then one growth step).
        d_min: A new vector must lie farther than this from every other, in units of the
            action range, in (0, 1].
        rho: Merge threshold on the mean square difference of two value columns over the
            remembered states, in the reward's units squared, >= 0 (0: never merge).
        memory: Number of last visited states on which the rules judge.
        n_tilings, tiles_per_dim, iht_size, obs_bounds: The tile coding, as in TileSarsa.
        alpha: Total step size in (0, 1] (each weight moves by ``alpha / n_tilings``).
        lam, gamma, epsilon, traces: As in TileSarsa.
        q_init: Initial value of every ``Q(s, a)``. Optimistic by default: on
            MountainCarContinuous (-0.1 a^2 per step, +100 at the flag) an agent that starts
            at 0 learns to stand still and never finds the flag.
        seed: Seed of every random choice the agent makes and of the env's first reset.

    Attributes:
        actions_: ``(n_actions_, *shape)`` the live action vectors, in the env's units.
        n_actions_: Number of live action vectors.
        weights_: ``(iht_size, n_actions_)`` weights of the live actions.
        n_cells: The number of live actions (not of tiles; the tiles in use are
            ``tile_coder_.n_used``).

    Episode records count in ``n_cells`` the live actions after the episode, in
    ``appends`` the vectors grown and in ``merges`` the merges of the pass that ran
    after it (if any), and in ``refused`` the growth steps refused there (every
    midpoint within ``d_min``, or ``max_actions`` reached).
    """

    size_unit = "actions"

    def __init__(
        self,
        env: gym.Env | str,
        *,
        init_actions: int = 3,
        fixed: bool = False,
        max_actions: int = 17,
        adapt_every: int = 25,
        d_min: float = 0.03,
        rho: float = 30.0,
        memory: int = 2000,
        n_tilings: int = 8,
        tiles_per_dim: int | Sequence[int] = 8,
        iht_size: int = 4096,
        obs_bounds: Sequence[tuple[float, float] | None] | None = None,
        alpha: float = 0.5,
        lam: float = 0.9,
        gamma: float = 0.99,
        epsilon: float = 0.05,
        q_init: float = 30.0,
        traces: str = "replacing",
        seed: int | None = None,
    ) -> None:
        check_sarsa_params(self, alpha, lam, gamma, epsilon, q_init, traces)
        self.init_actions = check_int("init_actions", init_actions, 1)
        self.fixed = check_bool("fixed", fixed)
        self.max_actions = check_int("max_actions", max_actions, 2)
        self.adapt_every = check_int("adapt_every", adapt_every, 1)
        self.d_min = check_range("d_min", d_min, 0.0, 1.0, low_open=True)
        self.rho = check_range("rho", rho, 0.0, np.inf, high_open=True)
        self.memory = check_int("memory", memory, 1)
        super().__init__(env, seed, n_tilings, tiles_per_dim, iht_size, obs_bounds)
        box = cast(spaces.Box, self.env.action_space)  # (a bounded Box: _check_spaces, in super().__init__)
        self._act_shape = tuple(box.shape)
        self._act_low = np.asarray(box.low, dtype=np.float64).ravel()
        self._act_high = np.asarray(box.high, dtype=np.float64).ravel()
        self._grid = uniform_actions(self.init_actions, self._act_low.shape[0])
        if not self.fixed and len(self._grid) > self.max_actions:
            raise ValueError(
                f"max_actions must be at least the initial grid's {len(self._grid)} actions "
                f"(init_actions ** action dims), not {self.max_actions}"
            )
        # Weight columns: the grid alone when fixed, else room for max_actions (never reallocated).
        self._slots = len(self._grid) if self.fixed else self.max_actions

    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        name = type(self).__name__
        if not isinstance(obs_space, spaces.Box) or len(obs_space.shape) != 1:
            raise ValueError(f"{name} needs a 1-D Box observation space, not {obs_space}")
        # Unsuitable spaces are ValueErrors, as in every avq agent (avq.agents._spaces).
        if isinstance(act_space, spaces.Discrete):
            raise ValueError(  # noqa: TRY004
                f"{name} quantizes a continuous (Box) action space, but this environment's actions are "
                f"already Discrete; use the other agents ('tiles', 'avq', 'grid'; see avq.AGENTS)"
            )
        if not isinstance(act_space, spaces.Box):
            raise ValueError(f"{name} needs a Box action space, not {act_space}")  # noqa: TRY004
        if not (
            np.all(np.isfinite(act_space.low))
            and np.all(np.isfinite(act_space.high))
            and np.all(act_space.high > act_space.low)
        ):
            raise ValueError(f"{name} needs a Box action space with finite bounds and low < high, not {act_space}")

    # -- learned state ------------------------------------------------------------------------------
    @property
    def n_actions(self) -> int:  # type: ignore[override]
        """Number of live action vectors (what ``predict`` chooses among)."""
        return self._n if self._is_setup else len(self._grid)

    @property
    def n_actions_(self) -> int:
        return self.n_actions

    @property
    def n_cells(self) -> int:
        return self.n_actions

    @property
    def actions_(self) -> np.ndarray:
        units = self._units[: self.n_actions] if self._is_setup else self._grid
        return self._to_env_units(units).reshape((-1,) + self._act_shape)

    @property
    def weights_(self) -> np.ndarray:
        return self._w[:, : self._n].copy()

    def _to_env_units(self, units: np.ndarray) -> np.ndarray:
        return self._act_low + units * (self._act_high - self._act_low)

    def _live_weights(self) -> np.ndarray:
        """The weight columns of the live actions (``q_values`` gives ``(b, n_actions_)``)."""
        return self._w[:, : self._n]

    def _setup(self) -> None:
        self._setup_tiles(self._slots)
        self._w0 = self.q_init / self.n_tilings
        self._units = np.zeros((self._slots, self._act_low.shape[0]))
        self._units[: len(self._grid)] = self._grid
        self._n = len(self._grid)
        self._refresh_env_actions()
        # The last `memory` visited states, as their active tiles (a ring buffer).
        self._recent = np.zeros((self.memory, self.n_tilings), dtype=np.int64)
        self._recent_count = 0

    def _refresh_env_actions(self) -> None:
        env_units = self._to_env_units(self._units[: self._n])
        self._env_actions = [v.reshape(self._act_shape).astype(np.float32) for v in env_units]

    def _sent_actions(self) -> list[np.ndarray]:
        return self._env_actions

    def _features(self, obs: Any) -> np.ndarray:
        """The active tiles, remembered among the last ``memory`` visited states."""
        active = super()._features(obs)
        self._recent[self._recent_count % self.memory] = active
        self._recent_count += 1
        return active

    def _values(self, active: np.ndarray) -> np.ndarray:
        """``Q(s, .)`` of the live actions in the state with these active tiles."""
        return self._w.take(active, axis=0)[:, : self._n].sum(axis=0)

    # -- the episode loop (Sutton & Barto 2018, §12.7): TileCodedSarsa's ---------------------------------
    def _end_episode(self) -> EpisodeRecord:
        grown = merges = refused = 0
        if not self.fixed and self.num_episodes % self.adapt_every == 0:
            merges = self.merge_pass()
            grown = self.grow_step()
            refused = 1 - grown
        return episode_record(self._ep_steps, self._ep_return, self._n, grown, merges, refused)

    # -- adapting the codebook (between episodes) -----------------------------------------------------
    def _remembered_values(self) -> np.ndarray:
        """``(N, n_actions_)`` values of the live actions in the remembered states."""
        states = self._recent[: min(self._recent_count, self.memory)]
        return self._w.take(states, axis=0)[:, :, : self._n].sum(axis=1)

    def grow_step(self) -> int:
        """Insert one action vector where ``plan_growth`` says; 1 if one was inserted, else 0."""
        if self._n >= self._slots:
            return 0
        plan = plan_growth(self._units[: self._n], self._remembered_values(), self.d_min)
        if plan is None:
            return 0
        g, j = plan
        c = self._n
        self._units[c] = (self._units[g] + self._units[j]) / 2.0
        self._w[:, c] = (self._w[:, g] + self._w[:, j]) / 2.0
        self._e[:, c] = 0.0
        self._n += 1
        self._refresh_env_actions()
        return 1

    def merge_pass(self) -> int:
        """Merge the pairs ``plan_merges`` finds; return how many merged.

        The merged action takes the lower slot, its vector from ``merged_vector``
        and its weights the mean of the pair's; the slots above the removed one move
        down in order, and the freed columns return to their initial weights.
        """
        pairs = plan_merges(self._units[: self._n], self._remembered_values(), self.rho)
        if not pairs:
            return 0
        removed = set()
        for i, j in pairs:
            self._units[i] = merged_vector(self._units[i], self._units[j])
            self._w[:, i] = (self._w[:, i] + self._w[:, j]) / 2.0
            removed.add(j)
        keep = [k for k in range(self._n) if k not in removed]
        n = len(keep)
        self._units[:n] = self._units[keep]
        self._w[:, :n] = self._w[:, keep]
        self._units[n:] = 0.0
        self._w[:, n:] = self._w0
        self._e[:] = 0.0
        self._n = n
        self._refresh_env_actions()
        return len(pairs)

    # -- acting ---------------------------------------------------------------------------------------
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, None]:
        """The action vector for one observation (float32, the action space's shape), or
        ``(b, *shape)`` for a batch; otherwise as :meth:`BaseAgent.predict`."""
        index, _ = super().predict(observation, state, episode_start, deterministic)
        return self.slot_actions(index), None

    def slot_actions(self, index: int | np.ndarray) -> np.ndarray:
        """The action vectors (float32, in the env's units) of live action slots."""
        idx = np.asarray(index, dtype=np.int64)
        out = self._to_env_units(self._units[idx]).astype(np.float32)
        return out.reshape(idx.shape + self._act_shape)

    # -- saving ---------------------------------------------------------------------------------------
    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        meta["recent_count"] = self._recent_count
        arrays["action_units"] = self._units[: self._n].copy()
        arrays["recent"] = self._recent[: min(self._recent_count, self.memory)].copy()
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        units, recent = arrays["action_units"], arrays["recent"]
        count = int(meta["recent_count"])
        dims = self._units.shape[1]
        if units.ndim != 2 or units.shape[1] != dims or not 1 <= len(units) <= self._slots:
            raise ValueError(f"action_units of shape {units.shape} do not fit (1..{self._slots}, {dims})")
        if not (np.all(units >= 0.0) and np.all(units <= 1.0)):
            raise ValueError("action_units lie outside the unit box")
        if self.fixed and not np.array_equal(units, self._grid):
            raise ValueError("a fixed agent's actions must be its initial grid")
        if count < 0 or recent.shape != (min(count, self.memory), self.n_tilings):
            raise ValueError(
                f"recent states of shape {recent.shape} do not fit recent_count {count} and memory {self.memory}"
            )
        if recent.size and (recent.min() < 0 or recent.max() >= self.iht_size):
            raise ValueError("recent states name tiles outside the weight table")
        super()._load_state_dict(meta, arrays)  # the counters, weights and tiles
        self._n = len(units)
        self._units[:] = 0.0
        self._units[: self._n] = units
        self._recent[: len(recent)] = recent
        self._recent_count = count
        self._refresh_env_actions()
