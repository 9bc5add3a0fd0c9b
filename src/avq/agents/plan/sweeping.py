"""Prioritized sweeping (Moore & Atkeson 1993) on one state per distinct observation: the model-based
baseline ``tabular-ps``; and what every agent that plans over a learned model shows of it
(:class:`ModelPlanner`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._numba import Compiled, direct_call
from avq._validate import PlanningSettings, check_bool, check_int, check_int_or_ints, check_planning_params
from avq.agents import _maze_loop
from avq.agents._per_step import PerStepAgent
from avq.agents._spaces import check_box_discrete, check_table_spaces, normalize_obs_bounds
from avq.agents.base import BaseAgent, EpisodeRecord, episode_record
from avq.agents.baselines.grid import bin_coordinates, uniform_grid
from avq.agents.baselines.table import greedy_over_rows, observation_key
from avq.agents.plan import model as _model
from avq.agents.plan.exploit import greedy_actions, greedy_floor
from avq.agents.plan.fused import PSTable, run_ps_grid_maze
from avq.agents.plan.model import Model
from avq.agents.plan.tabular import ps_step

__all__ = ["PrioritizedSweeping", "ModelPlanner"]


class ModelPlanner(BaseAgent):
    """What the agents that plan by prioritized sweeping over a learned :class:`~avq.agents.plan.model.Model`
    (``_model``, whose states are the agent's ``n_cells`` states or cells) show of it: ``q_``, the planned
    values, the model itself and the planner's counts; and their greedy policy, chosen on the model's plan
    without optimism (:func:`~avq.agents.plan.exploit.plan_without_optimism`: a pair not yet known worth the lowest
    return of an episode seen), planned again only when the model or that floor changed since (the key: its
    arrays, backups, states and edges, and the floor)."""

    _model: Model
    _greedy: tuple[tuple[float, ...], np.ndarray] | None = None

    def _greedy_q(self) -> np.ndarray:
        """What ``predict(deterministic=True)`` maximizes, a row per state: 1 for the greedy action
        (:func:`~avq.agents.plan.exploit.greedy_actions`), 0 for the others (docs: explanation/beyond-the-paper.md,
        The greedy policy)."""
        a, floor = self._model.a, greedy_floor(self.history_.lowest_return())
        key = (id(a), int(a.C[_model.BACKUPS]), int(a.C[_model.N_STATES]), int(a.C[_model.N_EDGES]), floor)
        if self._greedy is None or self._greedy[0] != key:
            choice = np.zeros_like(a.Q)
            best = greedy_actions(a, floor)
            choice[np.arange(len(best)), best] = 1.0
            self._greedy = (key, choice)
        return self._greedy[1]

    @property
    def q_(self) -> np.ndarray:
        return self._model.a.Q[: self.n_cells].copy()

    @property
    def model_(self) -> Model:
        """The learned model and its planner's queue, for inspection: ``n_states``, ``backups``, ``queued``,
        ``queue(s, priority)`` (queue a state for a backup) and ``sweep(budget)`` (back up at most ``budget``
        queued states, highest priority first)."""
        return self._model

    @property
    def backups_(self) -> int:
        return self._model.backups

    @property
    def queued_(self) -> int:
        return self._model.queued


class PrioritizedSweeping(PlanningSettings, ModelPlanner, PerStepAgent):
    """Model-based RL: a learned model of every (observation, action) pair and prioritized sweeping over it.

    Each distinct observation is a state (as in ``tabular``). The model counts, for each pair, its
    successors and the mean reward (src/avq/agents/plan/model.py), so it is right for stochastic tasks.
    A pair tried fewer than ``known_after`` times is worth ``v_opt`` (optimism, as in R-max: the agent
    goes to try it). After every step the pair's state is backed up from the model and at most
    ``n_backups`` more states, those whose values the change moves most, are backed up; the queue
    carries over to the next step. Actions are greedy on the planned values (ε-greedy with
    ``epsilon`` > 0), ties broken at random.

    Args:
        env: A Gymnasium environment (or registered id) with ``Discrete`` actions and a ``Discrete`` or
            ``Box`` observation space whose observations repeat exactly (the grid maze's ``(x, y)``), or
            any ``Box`` space with ``bins``.
        gamma: Discount γ of the planned values, in [0, 1]. With γ = 1 the values of a task whose
            rewards can be positive along a cycle do not converge; ``v_min`` bounds them from below.
        epsilon: Exploration rate on top of optimism, in [0, 1].
        v_opt: Value of a pair not yet known: at least what the best return could be (on the grid maze,
            the goal's reward, 10).
        v_min: Floor of every known value (below any true value of the task); in the greedy policy a pair not yet
            known is worth the lowest return of an episode seen (no higher than 0), ``v_min`` only until an episode
            has ended (:func:`avq.agents.plan.exploit.greedy_floor`).
        known_after: Transitions after which a pair's own statistics replace ``v_opt`` (1: at once, right
            for deterministic tasks; more for noisy ones).
        n_backups: Backups per step beyond the one of the pair just tried (0: no planning beyond it).
        tol: Smallest change of a value that is propagated to its predecessors.
        bins: None: a state per distinct observation. Else a state per bin of a uniform grid over the
            observation bounds, as ``grid`` cuts it: bins per dimension (an int, or one per dimension).
        obs_bounds: With ``bins``: ``(low, high)`` per dimension (None keeps the space's).
        max_states: Upper bound on the number of states; an observation beyond it is an error.
        fused: On ``avq/GridMaze-v0`` (standard wrappers only), run the maze and the agent in one compiled
            loop; the same results as stepping the environment from Python.
        seed: Seed of every random choice the agent makes and of the env's first reset.

    Attributes:
        q_: ``(k, m)`` planned action values, one row per observation seen.
        states_: ``(k, n)`` the observations, in the order first seen (Box spaces).
        n_cells: ``k``.
        backups_: backups done so far; ``queued_``: states waiting in the queue (0: converged).
    """

    _transient: ClassVar[dict[str, Any]] = {"_direct": None}

    def __init__(
        self,
        env: gym.Env | str,
        *,
        gamma: float = 1.0,
        epsilon: float = 0.0,
        v_opt: float = 10.0,
        v_min: float = -10_000.0,
        known_after: int = 1,
        n_backups: int = 100,
        tol: float = 0.01,
        bins: int | Sequence[int] | None = None,
        obs_bounds: Sequence[Sequence[float] | None] | None = None,
        max_states: int = 1_000_000,
        fused: bool = True,
        seed: int | None = None,
    ) -> None:
        check_planning_params(self, gamma, epsilon, v_opt, v_min, known_after, n_backups, tol)
        self.bins = None if bins is None else check_int_or_ints("bins", bins)
        self.obs_bounds = normalize_obs_bounds(obs_bounds)
        if self.obs_bounds is not None and self.bins is None:
            raise ValueError(
                "obs_bounds is the box that bins cuts: give bins too (or neither, for a state per distinct observation)"
            )
        self.max_states = check_int("max_states", max_states, 1)
        self.fused = check_bool("fused", fused)
        super().__init__(env, seed)
        if self.bins is not None:
            self._low, _, self._bins, self._bins_per_unit, self._strides = uniform_grid(
                self.env.observation_space, self.obs_bounds, self.bins
            )
            if math.prod(self._bins.tolist()) > 1 << 62:
                raise ValueError(
                    f"bins gives {math.prod(self._bins.tolist()):.3g} bins in {len(self._bins)} dimensions, "
                    "more than a bin index can hold; use fewer bins or avq-plan"
                )

    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        self._discrete = check_table_spaces("PrioritizedSweeping", obs_space, act_space)
        if self.bins is not None:
            check_box_discrete("PrioritizedSweeping with bins", obs_space, act_space, "it is a table already")

    # -- learned state ------------------------------------------------------------------
    @property
    def n_cells(self) -> int:
        return self._model.n_states if self._is_setup else 0

    @property
    def states_(self) -> np.ndarray:
        """The states' keys in the order first seen: observations ``(k, n)``, or ``(k, 1)`` bin or Discrete indices."""
        return np.array(self._keys, dtype=np.float64).reshape(len(self._keys), -1)

    def _setup(self) -> None:
        self._model = _model.Model(self.n_actions, float(self.v_opt), self.v_min, self.known_after, self.tol)
        self._index: dict[Any, int] = {}
        self._keys: list[Any] = []
        self._ep_row = self._ep_action = self._ep_steps = self._ep_new = 0
        self._ep_return = 0.0
        #: The compiled ps_step for the argument types of the last step that went through Numba's dispatcher
        #: (see _advance), or None.
        self._direct = None
        #: The fused loop for each maze's types (see _fused_runner).
        self._loops: dict[tuple, Compiled] = {}

    def _key(self, obs: Any) -> Any:
        """The state's key: its flat bin index with ``bins``, else the observation's (a Discrete index or a tuple)."""
        if self.bins is None:
            return observation_key(self.env.observation_space, obs)
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != self.env.observation_space.shape:
            raise ValueError(f"observation has shape {x.shape}; the space says {self.env.observation_space.shape}")
        return int(bin_coordinates(x, self._low, self._bins_per_unit, self._bins) @ self._strides)

    def _row(self, obs: Any, create: bool = True) -> int:
        key = self._key(obs)
        row = self._index.get(key)
        if row is not None or not create:
            return -1 if row is None else row
        if len(self._keys) >= self.max_states:
            raise ValueError(
                f"PrioritizedSweeping has seen {len(self._keys)} distinct observations (max_states); "
                "the observation space is too fine for a table: use an AVQ agent"
            )
        row = self._model.add_state()
        self._index[key] = row
        self._keys.append(key)
        self._ep_new += 1
        return row

    # -- the episode loop -----------------------------------------------------------------
    def _begin_episode(self, obs: Any) -> None:
        self._ep_steps = self._ep_new = 0
        self._ep_return = 0.0
        self._check_finite(obs, 0.0, 0)
        self._ep_row = self._row(obs)
        self._ep_action = self._decide(self._model.a.Q[self._ep_row])

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        # One compiled call per step (ps_step). After the first, through Numba's dispatcher, the compiled function
        # it chose is called directly (avq._numba.direct_call), which skips typing the model's record at every
        # call: the arguments keep their types (Model.reserve reallocates with the same dtypes, dimensions and
        # layout; the rest are ints, floats and a bool).
        draws, model, kernel = self._draws, self._model, ps_step
        gamma, epsilon, n_backups = self.gamma, self.epsilon, self.n_backups

        def update(s: int, a: int, r: float, obs: Any, terminated: bool) -> tuple[int, int]:
            s2 = self._row(obs)
            model.reserve(edges=1)
            draws.reserve()
            args = (model.a, draws.src, s, a, r, gamma, s2, terminated, epsilon, n_backups)
            direct = self._direct
            if direct is None:
                a = kernel(*args)
                self._direct = direct_call(kernel, args)
            else:
                a = direct(*args)
            return s2, int(a)

        self._ep_row, self._ep_action, n, ended = self._sarsa_steps(max_steps, self._ep_row, self._ep_action, update)
        return n, ended

    def _end_episode(self) -> EpisodeRecord:
        return episode_record(self._ep_steps, self._ep_return, self.n_cells, self._ep_new)

    def _fused_runner(self):
        maze = (
            _maze_loop.plan(self.env, grid_only=True)
            if self.fused and not self._discrete and self.bins is None
            else None
        )
        if maze is None or maze.dynamics.walls.size > self.max_states:
            return None  # (with fewer states than squares, the Python path says when max_states is reached)
        model = self._model
        # (called once per learn() or episode: directly after the first call, for this maze's types)
        mz = _maze_loop.maze_arguments(maze)
        loop = self._loops.setdefault(_maze_loop.maze_types(mz), Compiled(run_ps_grid_maze))

        def run(max_steps: int, max_episodes: int, max_records: int):
            row_of, keys = _maze_loop.grid_rows(self._index, maze.dynamics.walls.shape)
            T = np.array(
                [self._ep_row, self._ep_action, self._ep_steps, self._ep_new, int(self._in_episode)], dtype=np.int64
            )  # (indexed by fused.T_*)
            table = PSTable(row_of, keys, T, np.array([self._ep_return]))
            first_new = model.n_states
            steps, rows = _maze_loop.drive(
                maze,
                mz,
                loop,
                lambda: (model.a, table, self.gamma, self.epsilon, self.n_backups, self._rng),
                lambda: model.reserve(states=1, edges=1),
                max_steps,
                max_episodes,
                max_records,
            )
            _maze_loop.add_grid_rows(self._index, self._keys, keys, first_new, model.n_states)
            self._ep_row, self._ep_action, self._ep_steps, self._ep_new = (int(v) for v in T[:4])
            self._ep_return = float(table.TF[0])
            return steps, rows, bool(T[4])

        return run

    # -- queries ----------------------------------------------------------------------------
    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        return greedy_over_rows(self.env.observation_space, obs, self._row, self._greedy_q())

    def _obs_shape(self) -> tuple[int, ...]:
        return () if self._discrete else super()._obs_shape()

    # -- saving -----------------------------------------------------------------------------
    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        meta["episode"] = [self._ep_row, self._ep_action, self._ep_steps, self._ep_new, self._ep_return]
        arrays["states"] = self.states_
        arrays.update(self._model.state_dict())
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        super()._load_state_dict(meta, arrays)
        states = arrays["states"]
        self._model.load_state_dict(arrays)
        if len(states) != self._model.n_states:
            raise ValueError(f"{len(states)} observations for a model of {self._model.n_states} states")
        for row, x in enumerate(states):
            key = int(x[0]) if self._discrete or self.bins is not None else tuple(float(v) for v in x)
            self._index[key] = row
            self._keys.append(key)
        row, action, steps, new, ret = meta["episode"]
        self._ep_row, self._ep_action, self._ep_steps, self._ep_new = int(row), int(action), int(steps), int(new)
        self._ep_return = float(ret)
