"""Standard tabular Sarsa(λ): one value row per distinct observation, one decision per step."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import check_bool, check_int, check_sarsa_params
from avq.agents._td import epsilon_greedy, sarsa_lambda_update, sarsa_td_error
from avq.agents.base import BaseAgent, EpisodeRecord, episode_record

__all__ = ["TabularSarsa"]


class TabularSarsa(BaseAgent):
    """Sarsa(λ) with a table row for every distinct observation.

    Accepts ``Discrete`` observation spaces (row = observation) and small ``Box``
    spaces whose observations repeat exactly, such as the grid maze's ``(x, y)``
    (a row is created the first time an observation is seen, with ``q_init``).

    Args:
        env: A Gymnasium environment (or registered id) with ``Discrete`` actions.
        alpha: Step size, in (0, 1].
        lam: Trace decay λ, in [0, 1].
        gamma: Discount γ, in [0, 1].
        epsilon: Exploration rate, in [0, 1].
        q_init: Initial action value.
        traces: ``"replacing"`` or ``"accumulating"``.
        max_states: Upper bound on the number of rows; an observation beyond it is an error.
        fused: On ``avq/GridMaze-v0`` (standard wrappers only), run the maze and the
            agent in one compiled loop; same results as stepping the env from Python.
        seed: Seed of every random choice the agent makes and of the env's first reset.

    Attributes:
        q_: ``(k, m)`` action values, one row per observation seen.
        states_: ``(k, n)`` the observations, in the order first seen (Box spaces).
        n_cells: ``k``.
    """

    def __init__(
        self,
        env: gym.Env | str,
        *,
        alpha: float = 0.1,
        lam: float = 0.7,
        gamma: float = 1.0,
        epsilon: float = 0.1,
        q_init: float = 0.0,
        traces: str = "replacing",
        max_states: int = 1_000_000,
        fused: bool = True,
        seed: int | None = None,
    ) -> None:
        check_sarsa_params(self, alpha, lam, gamma, epsilon, q_init, traces)
        self.max_states = check_int("max_states", max_states, 1)
        self.fused = check_bool("fused", fused)
        super().__init__(env, seed)

    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        if not isinstance(act_space, spaces.Discrete):
            raise ValueError(f"TabularSarsa needs a Discrete action space, not {act_space}"
                             + ("; for continuous actions use the agent 'avq-actions' (or 'uniform-actions')"
                                if isinstance(act_space, spaces.Box) else ""))
        if not isinstance(obs_space, (spaces.Discrete, spaces.Box)):
            raise ValueError(f"TabularSarsa needs a Discrete or Box observation space, not {obs_space}")
        self._discrete = isinstance(obs_space, spaces.Discrete)

    @property
    def n_cells(self) -> int:
        return self._n if self._is_setup else 0

    @property
    def q_(self) -> np.ndarray:
        return self._q[: self._n].copy()

    @property
    def states_(self) -> np.ndarray:
        return np.array(self._keys, dtype=np.float64).reshape(self._n, -1)

    def _setup(self) -> None:
        cap = int(self.env.observation_space.n) if self._discrete else 256  # type: ignore[attr-defined]
        self._q = np.full((cap, self.n_actions), self.q_init)
        self._e = np.zeros((cap, self.n_actions))
        self._index: dict[Any, int] = {}
        self._keys: list[Any] = []
        self._n = 0
        self._ep_state = 0
        self._ep_action = 0
        self._ep_steps = 0
        self._ep_return = 0.0
        self._ep_new = 0

    def _key(self, obs: Any) -> Any:
        if self._discrete:
            return int(obs)
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != self.env.observation_space.shape:
            raise ValueError(f"observation has shape {x.shape}; the space says {self.env.observation_space.shape}")
        return tuple(x.tolist())

    def _row(self, obs: Any, create: bool = True) -> int:
        key = self._key(obs)
        row = self._index.get(key)
        if row is not None or not create:
            return -1 if row is None else row
        if self._n >= self.max_states:
            raise ValueError(
                f"TabularSarsa has seen {self._n} distinct observations (max_states); the observation "
                "space is too fine for a table: use 'grid', 'tiles' or an AVQ agent"
            )
        if self._n == self._q.shape[0]:
            cap = self._q.shape[0]
            self._q = np.concatenate([self._q, np.full((cap, self.n_actions), self.q_init)])
            self._e = np.concatenate([self._e, np.zeros((cap, self.n_actions))])
        row = self._n
        self._index[key] = row
        self._keys.append(key)
        self._n += 1
        self._ep_new += 1
        return row

    def _begin_episode(self, obs: np.ndarray) -> None:
        self._e[: self._n] = 0.0
        self._ep_steps = 0
        self._ep_return = 0.0
        self._ep_new = 0
        self._check_finite(obs, 0.0, 0)
        self._ep_state = self._row(obs)
        self._ep_action = epsilon_greedy(self._q[self._ep_state], self.epsilon, self._rng)

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        env = self.env
        s, a = self._ep_state, self._ep_action
        replacing = self.traces == "replacing"
        decay = self.gamma * self.lam
        n = 0
        ended = False
        while n < max_steps:
            obs, r, terminated, truncated, _ = env.step(a)
            n += 1
            self._check_finite(obs, r, self._ep_steps + n)
            r = float(r)
            self._ep_return += r
            s2 = self._row(obs)
            q = self._q
            if terminated:
                a2 = a
                delta = sarsa_td_error(q[s, a], r, self.gamma, 0.0, True)
            else:
                a2 = epsilon_greedy(q[s2], self.epsilon, self._rng)
                delta = sarsa_td_error(q[s, a], r, self.gamma, q[s2, a2], False)
            sarsa_lambda_update(q, self._e, s, a, delta, self.alpha, decay, replacing, self._n)
            s, a = s2, a2
            if terminated or truncated:
                ended = True
                break
        self._ep_state, self._ep_action = s, a
        self._ep_steps += n
        return n, ended

    def _end_episode(self) -> EpisodeRecord:
        return episode_record(self._ep_steps, self._ep_return, self._n, self._ep_new)

    def _fused_runner(self):
        from avq.agents.avq_sarsa import _fused_plan
        from avq.envs.grid_maze import GridMaze

        plan = _fused_plan(self.env) if self.fused else None
        if plan is None or not isinstance(plan[0], GridMaze) or self._discrete:
            return None
        base, time_limit, order = plan
        layout = base.layout
        h, w = layout.height, layout.width
        walls = np.ascontiguousarray(layout.walls)
        starts = np.ascontiguousarray(base._starts, dtype=np.int64)
        fixed = np.array(layout.start if base.start == "fixed" else (-1, -1), dtype=np.int64)
        limit = time_limit._max_episode_steps if time_limit is not None else 1 << 62

        def run(max_steps_budget: int, max_episodes: int, max_records: int):
            from avq.agents._fused import run_tabular_grid_maze

            while self._q.shape[0] < h * w:  # a row for every position, as _row would grow it
                cap = self._q.shape[0]
                self._q = np.concatenate([self._q, np.full((cap, self.n_actions), self.q_init)])
                self._e = np.concatenate([self._e, np.zeros((cap, self.n_actions))])
            row_of = np.full((h, w), -1, dtype=np.int64)
            keys = np.zeros((h * w, 2), dtype=np.int64)
            for key, row in self._index.items():
                row_of[int(key[1]), int(key[0])] = row
                keys[row] = int(key[0]), int(key[1])
            T = np.array([self._n, self._ep_state, self._ep_action, self._ep_steps, self._ep_new,
                          int(self._in_episode)], dtype=np.int64)
            TF = np.array([self._ep_return])
            elapsed = (time_limit._elapsed_steps or 0) if time_limit is not None else 0
            pos = np.array([base._x, base._y, elapsed], dtype=np.int64)
            rec = np.zeros((min(max_episodes, max_records), 7))
            steps, episodes = run_tabular_grid_maze(
                self._q, self._e, row_of, keys, T, TF, self.alpha, self.gamma, self.lam, self.epsilon,
                self.traces == "replacing", self._rng, base.np_random, walls, layout.goal[0], layout.goal[1],
                starts, fixed, limit, pos, max_steps_budget, min(max_episodes, max_records), rec)
            for row in range(self._n, int(T[0])):
                key = (float(keys[row, 0]), float(keys[row, 1]))
                self._index[key] = row
                self._keys.append(key)
            self._n, self._ep_state, self._ep_action, self._ep_steps, self._ep_new = (int(v) for v in T[:5])
            self._ep_return = float(TF[0])
            base._x, base._y = int(pos[0]), int(pos[1])
            if time_limit is not None:
                time_limit._elapsed_steps = int(pos[2])
            if order is not None:
                order._has_reset = True
            return steps, rec[:episodes], bool(T[5])

        return run

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        if self._discrete:
            space = self.env.observation_space
            bad = [o for o in obs if o != int(o) or not space.contains(int(o))]
            if bad:
                raise ValueError(f"observation {bad[0]!r} is not in the observation space {space}")
        out = np.zeros(len(obs), dtype=np.int64)
        for b, o in enumerate(obs):
            row = self._row(o, create=False)
            if row >= 0:
                out[b] = int(self._q[row].argmax())
        return out

    def _obs_shape(self) -> tuple[int, ...]:
        return () if self._discrete else super()._obs_shape()

    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        arrays["q"] = self.q_
        arrays["states"] = np.array(self._keys, dtype=np.float64).reshape(self._n, -1)
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        super()._load_state_dict(meta, arrays)
        q, states = arrays["q"], arrays["states"]
        if q.ndim != 2 or q.shape[1] != self.n_actions or len(states) != len(q):
            raise ValueError(f"array shapes q {q.shape}, states {states.shape} do not fit {self.n_actions} actions")
        for row in states:
            self._row(int(row[0]) if self._discrete else row)
        self._q[: len(q)] = q
