"""Standard tabular Sarsa(λ): one value row per distinct observation, one decision per step."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import check_bool, check_int, check_sarsa_params
from avq.agents import _maze_loop
from avq.agents._spaces import check_table_spaces
from avq.agents._td import SarsaParams
from avq.agents.baselines.fused import Table, run_tabular_grid_maze
from avq.agents.baselines.table import TableSarsa, greedy_over_rows, observation_key

__all__ = ["TabularSarsa"]


class TabularSarsa(TableSarsa):
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
        self._discrete = check_table_spaces("TabularSarsa", obs_space, act_space)

    @property
    def q_(self) -> np.ndarray:
        return self._q[: self._n].copy()

    @property
    def states_(self) -> np.ndarray:
        return np.array(self._keys, dtype=np.float64).reshape(self._n, -1)

    def _setup(self) -> None:
        self._make_table(int(self.env.observation_space.n) if self._discrete else 256)  # type: ignore[attr-defined]
        self._index: dict[Any, int] = {}
        self._keys: list[Any] = []

    def _key(self, obs: Any) -> Any:
        return observation_key(self.env.observation_space, obs)

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
        self._grow_table(self._n + 1)
        row = self._n
        self._index[key] = row
        self._keys.append(key)
        self._n += 1
        self._ep_new += 1
        return row

    def _fused_runner(self):
        maze = _maze_loop.plan(self.env, grid_only=True) if self.fused and not self._discrete else None
        if maze is None or maze.dynamics.walls.size > self.max_states:
            return None  # (with fewer rows than squares, the Python path says when max_states is reached)
        shape = maze.dynamics.walls.shape
        mz = _maze_loop.maze_arguments(maze)

        def run(max_steps: int, max_episodes: int, max_records: int):
            self._grow_table(shape[0] * shape[1])  # a row for every position, as _row would grow it
            row_of, keys = _maze_loop.grid_rows(self._index, shape)
            T = np.array(
                [self._n, self._ep_row, self._ep_action, self._ep_steps, self._ep_new, int(self._in_episode)],
                dtype=np.int64,
            )
            TF = np.array([self._ep_return])
            table = Table(self._q, self._e, self._act, row_of, keys, T, TF)
            params = SarsaParams(self.epsilon, self.alpha, self.gamma, self.lam, self.traces == "replacing")
            steps, rows = _maze_loop.drive(
                maze,
                mz,
                run_tabular_grid_maze,
                lambda: (table, params, self._rng),
                lambda: None,
                max_steps,
                max_episodes,
                max_records,
            )
            _maze_loop.add_grid_rows(self._index, self._keys, keys, self._n, int(T[0]))
            self._n, self._ep_row, self._ep_action, self._ep_steps, self._ep_new = (int(v) for v in T[:5])
            self._ep_return = float(TF[0])
            return steps, rows, bool(T[5])

        return run

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        return greedy_over_rows(self.env.observation_space, obs, self._row, self._q)

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
