"""Sarsa(λ) on an adaptive vector quantization of the observation space (SPEC §1-§5)."""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq.agents._td import epsilon_greedy, sarsa_lambda_update, sarsa_td_error
from avq.agents._spaces import normalize_obs_bounds, resolve_bounds
from avq.agents.base import BaseAgent, EpisodeRecord, check_int, check_range, check_sarsa_params
from avq.quantizer import Codebook
from avq.rules import APPEND, CHI, collision_rule, may_append, merged_values, similar_pairs

__all__ = ["AVQSarsa"]


class AVQSarsa(BaseAgent):
    """Sarsa(λ) on the Voronoi cells of a growing and merging codebook.

    The agent keeps a codebook of vectors in observation space; the cell of an
    observation (its nearest vector under the scaled metric) is the aggregate state
    that Sarsa(λ) learns on. In each cell it takes one ε-greedy decision and repeats
    it until the cell changes, a collision is reported, or the episode ends
    (SPEC §2). Collisions append vectors (SPEC §3); after every ``merge_every``
    episodes, mutually nearest cells with similar action values are merged (SPEC §4).

    Args:
        env: A Gymnasium environment (or registered id) with a ``Box`` observation
            space and ``Discrete`` actions.
        alpha: Step size, in (0, 1].
        lam: Trace decay λ, in [0, 1].
        gamma: Discount γ, in [0, 1].
        epsilon: Exploration rate of ε-greedy, in [0, 1].
        d_min: Minimum resolution (scaled units), >= 0. No vector is appended within
            ``d_min`` of an existing one; a collision within ``d_min`` of the current
            cell's vector sets that action's value to ``chi`` instead.
        rho: Merge threshold on the mean squared difference of two profiles, >= 0.
        chi: Value given to an action that hits an obstacle, < 0.
        q_init: Initial action value of the first cell.
        traces: ``"replacing"`` or ``"accumulating"`` eligibility traces.
        merge_every: Run a merge pass after every this many episodes; 0 never merges.
        merge_age: A cell may merge only after this many complete episodes of its own
            (0, the paper: at once). Cells made by the value-change trigger start as
            copies of their parent, so without an age they would merge back at once.
        value_trigger: TD-error magnitude ``theta`` that appends the transition's end
            state (SPEC §3, optional trigger), terminal states included (a cell at a
            failure state sharpens the partition where it matters); None turns it off.
        reward_trigger: On a step without a collision, a reward that differs from the
            previous step's (same episode) by at least this much appends the new
            observation as a cell inheriting the current cell's profile, which ends the
            aggregate transition; None turns it off. For tasks without collisions.
        scale: Per-dimension scale of the metric: a number or a sequence; None takes
            ``high - low`` of the observation space (every bound must be finite).
        obs_bounds: Instead of ``scale``: one ``(low, high)`` per dimension (None keeps the
            space's) from which the scale ``high - low`` is taken; needed for unbounded
            dimensions such as CartPole's velocities.
        max_cells: Upper bound on the codebook size; at the bound, appends are refused
            (counted in the episode record as ``refused``).
        seed: Seed of every random choice the agent makes and of the environment's
            first reset.

    The defaults are those of ``make_agent("avq-paper")`` except the metric: the
    class scales by the observation bounds (so ``d_min = 0.05`` is 5% of each
    range), while ``avq-paper`` uses the paper's plain Euclidean distance
    (``scale=1``, ``d_min=1`` grid unit).

    Attributes:
        codebook_: ``(p, n)`` codebook vectors.
        q_: ``(p, m)`` action values of the cells.
        n_cells: ``p``.
        history_: one record per finished episode: ``episode, steps, return, n_cells,
            appends, merges, refused, decisions, wall_s``.

    Order of operations on a collision (the paper leaves it open): the growth rule
    runs first (it appends a cell and/or assigns ``chi``), then the transition is
    learned like any other, from the cell the observation now belongs to.
    """

    def __init__(
        self,
        env: gym.Env | str,
        *,
        alpha: float = 0.5,
        lam: float = 0.7,
        gamma: float = 1.0,
        epsilon: float = 0.05,
        d_min: float = 0.05,
        rho: float = 5.0,
        chi: float = -50.0,
        q_init: float = 5.0,
        traces: str = "replacing",
        merge_every: int = 1,
        merge_age: int = 0,
        value_trigger: float | None = None,
        reward_trigger: float | None = None,
        scale: float | Sequence[float] | None = None,
        obs_bounds: Sequence[Sequence[float] | None] | None = None,
        max_cells: int = 10_000,
        seed: int | None = None,
    ) -> None:
        check_sarsa_params(self, alpha, lam, gamma, epsilon, q_init, traces)
        self.d_min = check_range("d_min", d_min, 0.0, np.inf, high_open=True)
        self.rho = check_range("rho", rho, 0.0, np.inf, high_open=True)
        self.chi = check_range("chi", chi, -np.inf, 0.0, low_open=True, high_open=True)
        self.merge_every = check_int("merge_every", merge_every, 0)
        self.merge_age = check_int("merge_age", merge_age, 0)
        self.value_trigger = (
            None if value_trigger is None
            else check_range("value_trigger", value_trigger, 0.0, np.inf, low_open=True, high_open=True)
        )
        self.reward_trigger = (
            None if reward_trigger is None
            else check_range("reward_trigger", reward_trigger, 0.0, np.inf, low_open=True, high_open=True)
        )
        self.max_cells = check_int("max_cells", max_cells, 1)
        self.scale = scale
        self.obs_bounds = normalize_obs_bounds(obs_bounds)
        super().__init__(env, seed)
        self._scale = self._resolve_scale(scale, self.obs_bounds)

    # -- spaces and scale ---------------------------------------------------------------
    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        if isinstance(obs_space, spaces.Discrete):
            raise ValueError(
                "AVQSarsa needs a Box observation space, but this environment's is Discrete: "
                "there is nothing to quantize; use the 'tabular' agent (avq.TabularSarsa)"
            )
        if not isinstance(obs_space, spaces.Box) or len(obs_space.shape) != 1:
            raise ValueError(f"AVQSarsa needs a 1-D Box observation space, not {obs_space}")
        if not isinstance(act_space, spaces.Discrete):
            raise ValueError(f"AVQSarsa needs a Discrete action space, not {act_space}")

    def _resolve_scale(self, scale: Any, obs_bounds: Any) -> np.ndarray:
        space = self.env.observation_space
        n = space.shape[0]
        if scale is not None and obs_bounds is not None:
            raise ValueError("give scale or obs_bounds, not both")
        if scale is None:
            low, high = resolve_bounds(space, obs_bounds)
            return high - low
        try:
            s = np.broadcast_to(np.asarray(scale, dtype=np.float64), (n,)).copy()
        except (ValueError, TypeError):
            raise ValueError(f"scale must be a number or {n} numbers, not {scale!r}") from None
        bad = np.flatnonzero(~(np.isfinite(s) & (s > 0)))
        if bad.size:
            raise ValueError(f"scale must be finite and > 0; dimension {int(bad[0])} has {s[bad[0]]}")
        return s

    # -- learned state ------------------------------------------------------------------
    @property
    def n_cells(self) -> int:
        return self._cb.size if self._is_setup else 0

    @property
    def codebook_(self) -> np.ndarray:
        return self._cb.vectors.copy()

    @property
    def q_(self) -> np.ndarray:
        return self._q[: self._cb.size].copy()

    def _setup(self) -> None:
        n = self.env.observation_space.shape[0]
        self._cb = Codebook(n, self._scale, capacity=64)
        self._q = np.zeros((64, self.n_actions))
        self._e = np.zeros((64, self.n_actions))
        self._born = np.zeros(64, dtype=np.int64)  # episode (1-based) in which each cell was created
        self._ep = _Episode()

    def _ensure_capacity(self) -> None:
        cap = self._q.shape[0]
        if self._cb.size >= cap:
            for name in ("_q", "_e", "_born"):
                old = getattr(self, name)
                new = np.zeros((2 * cap,) + old.shape[1:], dtype=old.dtype)
                new[:cap] = old
                setattr(self, name, new)

    def _as_obs(self, obs: Any, step: int) -> np.ndarray:
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != self._cb_shape:
            raise ValueError(f"observation at step {step} has shape {x.shape}; the space says {self._cb_shape}")
        return x

    @property
    def _cb_shape(self) -> tuple[int, ...]:
        return (self._cb.n_dims,)

    # -- the rules of the paper -----------------------------------------------------------
    def _append(self, x: np.ndarray, parent: int) -> int:
        """Append ``x`` as a cell whose profile is a copy of ``parent``'s (SPEC §3)."""
        self._ensure_capacity()
        c = self._cb.append(x)
        self._q[c] = self._q[parent]
        self._e[c] = 0.0
        self._born[c] = self.num_episodes + 1
        self._ep.appends += 1
        return c

    def _may_append(self, dist_nearest: float) -> bool:
        """Whether a point at ``dist_nearest`` from its nearest vector may become a vector."""
        if not may_append(dist_nearest, self.d_min):
            return False
        if self._cb.size >= self.max_cells:
            self._ep.refused += 1
            return False
        return True

    def _grow_on_collision(self, x: np.ndarray, i: int, a: int, j: int, dist_j: float) -> int:
        """Apply :func:`avq.rules.collision_rule` at ``x`` (nearest vector ``j`` at ``dist_j``).

        Returns the cell ``x`` belongs to afterwards.
        """
        dist_i = dist_j if j == i else self._cb.distance(i, x)
        outcome = collision_rule(dist_i, dist_j, self.d_min)
        if outcome == CHI:
            self._q[i, a] = self.chi
        elif outcome == APPEND and self._may_append(dist_j):
            j = self._append(x, parent=i)
            self._q[j, a] = self.chi  # the rule at c itself: ||y_c - x|| = 0 <= d_min
        return j

    def _grow_on_value_change(self, x: np.ndarray, j: int, delta: float) -> int:
        """SPEC §3, optional value-change trigger. Returns the cell of ``x`` afterwards."""
        if self.value_trigger is None or abs(delta) < self.value_trigger:
            return j
        if not self._may_append(self._cb.distance(j, x)):
            return j
        return self._append(x, parent=j)

    def _merge_pass(self) -> int:
        """SPEC §4: merge every mutually nearest pair whose profiles differ by less than ``rho``.

        With ``merge_age > 0``, a pair merges only if both cells have existed for at
        least ``merge_age`` complete episodes after the one that created them.
        """
        pairs = similar_pairs(self._cb.mutual_nearest_pairs(), self._q, self.rho)
        if self.merge_age and len(pairs):
            age = self.num_episodes - self._born[: self._cb.size]
            pairs = pairs[(age[pairs[:, 0]] >= self.merge_age) & (age[pairs[:, 1]] >= self.merge_age)]
        if len(pairs) == 0:
            return 0
        p = self._cb.size
        mapping = self._cb.merge(pairs)
        n_new = self._cb.size
        self._q[:n_new] = merged_values(self._q[:p], mapping, n_new)
        self._q[n_new:p] = 0.0
        self._e[:p] = 0.0
        born = self._born[:p].copy()
        self._born[mapping] = born  # survivors keep their birth; merged cells are new
        self._born[mapping[pairs[:, 0]]] = self.num_episodes
        return len(pairs)

    # -- the episode loop (SPEC §2, §5) ---------------------------------------------------
    def _begin_episode(self, obs: np.ndarray) -> None:
        x = self._as_obs(obs, 0)
        if self._cb.size == 0:
            # SPEC §3: the codebook starts with the very first observation.
            self._cb.append(x)
            self._q[0] = self.q_init
        self._e[: self._cb.size] = 0.0
        ep = self._ep
        ep.reset()
        ep.cell = self._cb.nearest(x)[0]
        ep.action = epsilon_greedy(self._q[ep.cell], self.epsilon, self._rng)
        ep.decisions = 1

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        env, cb, ep = self.env, self._cb, self._ep
        gamma, replacing = self.gamma, self.traces == "replacing"
        i, a = ep.cell, ep.action
        ret, disc = ep.ret, ep.disc
        n = 0
        ended = False
        while n < max_steps:
            obs, r, terminated, truncated, info = env.step(a)
            n += 1
            r = float(r)
            x = self._as_obs(obs, ep.steps + n)
            ret += disc * r
            disc *= gamma
            ep.episode_return += r
            collision = bool(info.get("collision", False))
            j, dist_j = cb.nearest(x)
            if self.reward_trigger is not None:
                jump = ep.steps + n > 1 and abs(r - ep.prev_reward) >= self.reward_trigger
                ep.prev_reward = r
                if jump and not collision and self._may_append(dist_j):
                    j = self._append(x, parent=i)
            if j == i and not (collision or terminated or truncated):
                continue
            # The aggregate transition (i, a) -> j ends here.
            if collision:
                j = self._grow_on_collision(x, i, a, j, dist_j)
            q = self._q
            if terminated:
                a_next = a
                delta = sarsa_td_error(q[i, a], ret, disc, 0.0, True)
            else:
                a_next = epsilon_greedy(q[j], self.epsilon, self._rng)
                delta = sarsa_td_error(q[i, a], ret, disc, q[j, a_next], False)
            sarsa_lambda_update(q, self._e, i, a, delta, self.alpha, disc * self.lam, replacing, cb.size)
            if self.value_trigger is not None:
                j = self._grow_on_value_change(x, j, delta)
            i, a = j, a_next
            ret, disc = 0.0, 1.0
            if terminated or truncated:
                ended = True
                break
            ep.decisions += 1
        ep.cell, ep.action, ep.ret, ep.disc = i, a, ret, disc
        ep.steps += n
        return n, ended

    def _end_episode(self) -> EpisodeRecord:
        ep = self._ep
        merges = 0
        if self.merge_every and (self.num_episodes % self.merge_every == 0):
            merges = self._merge_pass()
        return {
            "steps": ep.steps,
            "return": ep.episode_return,
            "n_cells": self._cb.size,
            "appends": ep.appends,
            "merges": merges,
            "refused": ep.refused,
            "decisions": ep.decisions,
        }

    # -- queries -----------------------------------------------------------------------------
    def cells(self, observations: np.ndarray) -> np.ndarray:
        """The cell index of each observation (a batch ``(b, n)``)."""
        if not self._is_setup or self._cb.size == 0:
            raise RuntimeError("AVQSarsa has no codebook yet; call learn() first")
        return self._cb.nearest_batch(np.asarray(observations, dtype=np.float64))

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        if self._cb.size == 0:
            return np.zeros(len(obs), dtype=np.int64)
        cells = self._cb.nearest_batch(obs)
        return self._q[cells].argmax(axis=1).astype(np.int64)

    # -- saving ---------------------------------------------------------------------------------
    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        arrays.update(codebook=self.codebook_, q=self.q_, born=self._born[: self._cb.size].copy())
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        super()._load_state_dict(meta, arrays)
        codebook, q = arrays["codebook"], arrays["q"]
        n = self.env.observation_space.shape[0]
        if codebook.ndim != 2 or codebook.shape[1] != n or q.shape != (codebook.shape[0], self.n_actions):
            raise ValueError(f"array shapes codebook {codebook.shape}, q {q.shape} do not fit ({n} dims, {self.n_actions} actions)")
        for row in codebook:
            self._ensure_capacity()
            self._cb.append(row)
        self._q[: len(q)] = q
        born = arrays.get("born", np.zeros(len(q), dtype=np.int64))
        if born.shape != (len(q),):
            raise ValueError(f"array born has shape {born.shape}; expected ({len(q)},)")
        self._born[: len(q)] = born


class _Episode:
    """The agent's position inside the current episode, kept between ``_advance`` calls."""

    __slots__ = ("cell", "action", "ret", "disc", "steps", "episode_return", "appends", "refused", "decisions",
                 "prev_reward")

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.cell = 0
        self.action = 0
        self.ret = 0.0  # discounted return of the aggregate transition so far
        self.disc = 1.0  # gamma ** k for the k steps of the transition so far
        self.steps = 0
        self.episode_return = 0.0
        self.appends = 0
        self.refused = 0
        self.decisions = 0
        self.prev_reward = 0.0  # reward of the previous primitive step (reward trigger)
