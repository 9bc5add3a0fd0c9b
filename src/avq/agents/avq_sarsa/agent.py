"""Sarsa(λ) on an adaptive vector quantization of the observation space (docs/explanation/paper.md#setting-§5)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from avq._validate import (
    SarsaSettings,
    check_bool,
    check_choice,
    check_int,
    check_optional,
    check_range,
    check_sarsa_params,
)
from avq.agents import _maze_loop
from avq.agents._maze_loop import N_R
from avq.agents._params import pack_params
from avq.agents._spaces import ScaledMetric
from avq.agents.avq_sarsa import episode_end, generic, kernels as core
from avq.agents.avq_sarsa.fused import fused_loop
from avq.agents.avq_sarsa.generic import GenericPath
from avq.agents.base import EpisodeRecord, episode_record
from avq.quantizer import Codebook

__all__ = ["AVQSarsa"]


class AVQSarsa(ScaledMetric, SarsaSettings, GenericPath):
    """Sarsa(λ) on the Voronoi cells of a growing and merging codebook.

    The agent keeps a codebook of vectors in observation space; the cell of an
    observation (its nearest vector under the scaled metric) is the aggregate state
    that Sarsa(λ) learns on. In each cell it takes one ε-greedy decision and repeats
    it until the cell changes, a collision is reported, or the episode ends
    (docs/explanation/paper.md#acting), or (``max_repeat``) for at most a number of steps. Collisions append vectors (docs/explanation/paper.md#growing); after every ``merge_every``
    episodes, mutually nearest cells with similar action values are merged (docs/explanation/paper.md#merging).

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
        epsilon_decay: Beyond the paper: after ``k`` episodes the exploration rate is
            ``max(epsilon_min, epsilon * epsilon_decay ** k)`` (1, the default: constant).
        epsilon_min: The floor of that schedule.
        alpha_decay: Beyond the paper: after ``k`` episodes the step size is
            ``max(alpha_min, alpha * alpha_decay ** k)`` (1, the default: constant).
        alpha_min: The floor of that schedule.
        explore_bonus: Beyond the paper: count-based exploration. The greedy part of ε-greedy
            (while learning) decides on ``Q[i, a] + explore_bonus / sqrt(1 + n[i, a])``, with
            ``n[i, a]`` the decisions taken with ``a`` in cell ``i`` (summed when cells merge,
            0 for a new cell); 0 (the paper): on ``Q`` alone. ``BaseAgent.predict`` always uses ``Q``.
        collision_split: Beyond the paper: on a collision within ``d_min`` of the
            cell's own vector, where the paper sets ``Q[i, a] = chi`` for the whole
            cell, split instead when ``a`` is the cell's greedy action and ``x`` is not
            the vector itself: append ``x`` as a copy of the cell with ``Q[c, a] = chi``.
            A cell then keeps an action that is right for most of it, and the squares
            where it hits a wall get cells of their own.
        cycle_split: Beyond the paper: when two greedy decisions in a row lead from a cell
            ``j`` to another cell and straight back into ``j`` (a cycle the greedy policy
            would repeat for ever, typical of a cell whose squares need opposite actions),
            split off the observation of the return as a copy of ``j``, unless it is ``j``'s
            own vector. Within ``d_min``, like ``collision_split``; counted in ``refused`` at
            ``max_cells``.
        adapt_rate: Beyond the paper: after every step without a collision, move the vector of
            the observation's cell toward it by this fraction of the distance (online k-means;
            0, the paper: vectors stay where they were placed).
        prune_after: Beyond the paper: after every episode, remove the cells in which the agent has
            taken no decision for this many episodes (and that are at least that old); 0 never
            prunes. Removals are not counted in the episode record (``n_cells`` shows them).
        make_room: Beyond the paper: when ``max_cells`` refused growth during an episode, the merge
            pass after it merges as many more of its candidate pairs, those with the same greedy
            action and the most similar profiles first (whatever ``rho``), so that the budget goes
            where growth is asked for.
        merge_pairs: Which pairs the merge pass considers. ``"mutual"`` (the paper,
            docs/explanation/paper.md#merging): each the other's unique nearest vector (Fig. 2's strict ``<``).
            ``"mutual_ties"``: a tie for the nearest goes to the lowest index instead of
            blocking the pair (ties are common on integer grids). ``"nearest"``: each
            cell with its nearest, mutual or not, closest pairs first, each cell in at
            most one pair per pass.
        merge_same_action: Merge a pair only if both cells have the same greedy action
            (beyond the paper: a merge then never changes the action taken anywhere in
            the two cells; the paper merges on similar profiles alone).
        value_trigger: TD-error magnitude ``theta`` that appends the transition's end
            state (docs/explanation/paper.md#growing, optional trigger), terminal states included (a cell at a
            failure state sharpens the partition where it matters); None turns it off.
        reward_trigger: On a step without a collision, a reward that differs from the
            previous step's (same episode) by at least this much appends the new
            observation as a cell inheriting the current cell's profile, which ends the
            aggregate transition; None turns it off. For tasks without collisions.
        scale: Per-dimension scale of the metric. ``"auto"`` (the default): ``high - low`` of the
            observation bounds (``obs_bounds`` or the space's) where they are finite, and where they
            are not (CartPole's velocities, say) an estimate from the observations: ``AUTO_SCALE_STDS``
            (4) standard deviations of the first ``scale_warmup`` observations, brought up to date at
            the end of every episode until then, and fixed after (1 before the first episode ends,
            and for as long as the dimension has not varied). A number or a sequence: that scale.
            None: ``high - low`` of the bounds, every one of which must be finite. ``"spread"``: every
            dimension is estimated from the observations, even where the bounds are finite (their range is used
            only until the first episode ends); a dimension that ``obs_bounds`` bounds keeps that range. For
            tasks whose bounds are far wider than what a run visits.
        scale_warmup: With ``scale="auto"`` or ``"spread"``: the number of first observations (resets included)
            from which the scale of the dimensions without finite bounds is estimated, >= 2.
        scale_factor: A number or one per dimension (each > 0) by which the metric's scale is multiplied,
            whatever its source (``scale``, the bounds, or the estimate of ``"auto"`` and ``"spread"``): a
            dimension of factor 2 counts half as much in the distance, so its cells are twice as wide. For a
            task whose decisions depend more on some dimensions than on others (Acrobot's velocities).
        obs_bounds: One ``(low, high)`` per dimension (None keeps the space's) from which the
            scale ``high - low`` is taken, with ``scale="auto"`` or None.
        ignore_noise: With ``scale="auto"`` or ``"spread"``: once ``scale_warmup`` observations are counted, a
            dimension that the observation before does not predict (drawn afresh each step: ``avq.agents._noise``),
            or whose change it does not (a slow drift), gets an infinite scale, so the distance and the cells ignore
            it; a drifting one gets its scale back if, after 30,000 observations, it is found to matter.
        max_repeat: Beyond the paper: a decision ends after at most this many primitive steps,
            even in the same cell (>= 1; None, the paper: it is repeated until the cell changes).
            It is then learned like a decision that ended in another cell: the Sarsa(λ) update of
            ``(i, a) -> (i, a')`` with the return of its steps, and the value-change trigger. On
            balancing tasks one long repetition can be fatal; on the mazes it is None.
        max_cells: Upper bound on the codebook size; at the bound, appends are refused
            (counted in the episode record as ``refused``).
        fused: On ``avq/GridMaze-v0`` and ``avq/RobotMaze-v0`` with noise-free sonar (as
            made by ``gymnasium.make``, with its standard wrappers), run the maze's
            dynamics and the agent in one compiled loop.
            Same results as stepping the environment from Python, much faster; the
            environment object is brought up to date after every ``BaseAgent.learn`` call.
            False always steps the environment from Python.
        seed: Seed of every random choice the agent makes and of the environment's
            first reset.

    The defaults are those of ``make_agent("avq-paper")`` except the metric: the
    class scales by the observation bounds (so ``d_min = 0.05`` is 5% of each
    range), while ``avq-paper`` uses the paper's plain Euclidean distance
    (``scale=1``, ``d_min=1`` grid unit). The named agents' defaults, those documented
    and measured, are in the data files ``avq/agents/defaults/*.yaml``.

    Attributes:
        scale_: ``(n,)`` the metric's scale in force (``scale`` resolved, and estimated where
            ``scale="auto"`` estimates it; ``BaseAgent.get_params()`` keeps ``scale`` as given).
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
        merge_same_action: bool = False,
        merge_pairs: str = "mutual",
        collision_split: bool = False,
        cycle_split: bool = False,
        adapt_rate: float = 0.0,
        prune_after: int = 0,
        make_room: bool = False,
        epsilon_decay: float = 1.0,
        epsilon_min: float = 0.0,
        alpha_decay: float = 1.0,
        alpha_min: float = 0.0,
        explore_bonus: float = 0.0,
        value_trigger: float | None = None,
        reward_trigger: float | None = None,
        scale: float | Sequence[float] | str | None = "auto",
        scale_warmup: int = 1000,
        scale_factor: float | Sequence[float] = 1.0,
        obs_bounds: Sequence[Sequence[float] | None] | None = None,
        ignore_noise: bool = True,
        max_cells: int = 10_000,
        max_repeat: int | None = None,
        fused: bool = True,
        seed: int | None = None,
    ) -> None:
        check_sarsa_params(self, alpha, lam, gamma, epsilon, q_init, traces)
        self.d_min = check_range("d_min", d_min, 0.0, np.inf, high_open=True)
        self.rho = check_range("rho", rho, 0.0, np.inf, high_open=True)
        self.chi = check_range("chi", chi, -np.inf, 0.0, low_open=True, high_open=True)
        self.merge_every = check_int("merge_every", merge_every, 0)
        self.merge_age = check_int("merge_age", merge_age, 0)
        self.merge_same_action = check_bool("merge_same_action", merge_same_action)
        self.merge_pairs = check_choice("merge_pairs", merge_pairs, core.MERGE_PAIRS)
        self.epsilon_decay = check_range("epsilon_decay", epsilon_decay, 0.0, 1.0, low_open=True)
        self.epsilon_min = check_range("epsilon_min", epsilon_min, 0.0, 1.0)
        self.alpha_decay = check_range("alpha_decay", alpha_decay, 0.0, 1.0, low_open=True)
        self.alpha_min = check_range("alpha_min", alpha_min, 0.0, 1.0)
        self.explore_bonus = check_range("explore_bonus", explore_bonus, 0.0, np.inf, high_open=True)
        for name, start, decay, floor in (
            ("alpha", self.alpha, self.alpha_decay, self.alpha_min),
            ("epsilon", self.epsilon, self.epsilon_decay, self.epsilon_min),
        ):
            if decay < 1.0 and floor > start:
                raise ValueError(
                    f"{name}_min ({floor}) must not exceed {name} ({start}): the schedule decays "
                    f"from {name} down to {name}_min"
                )
        self.collision_split = check_bool("collision_split", collision_split)
        self.cycle_split = check_bool("cycle_split", cycle_split)
        self.adapt_rate = check_range("adapt_rate", adapt_rate, 0.0, 1.0, high_open=True)
        self.prune_after = check_int("prune_after", prune_after, 0)
        self.make_room = check_bool("make_room", make_room)
        positive = dict(low=0.0, high=np.inf, low_open=True, high_open=True)
        self.value_trigger = check_optional(check_range, "value_trigger", value_trigger, **positive)
        self.reward_trigger = check_optional(check_range, "reward_trigger", reward_trigger, **positive)
        self.max_cells = check_int("max_cells", max_cells, 1)
        self.max_repeat = check_optional(check_int, "max_repeat", max_repeat, 1)
        self.fused = check_bool("fused", fused)
        super().__init__(env, seed, scale, scale_warmup, scale_factor, obs_bounds, ignore_noise)

    # -- spaces and scale ---------------------------------------------------------------
    def _update_scale(self) -> None:
        """``scale="auto"``: the scale of each dimension without finite bounds becomes ``AUTO_SCALE_STDS``
        standard deviations of the observations counted (where that is > 0). The codebook keeps its vectors
        in observation units, so the metric re-expresses them; only the cached pairs of the merge pass depend
        on it, and a new geometry version recomputes them."""
        if self._refresh_metric(self._spread, self._inv_scale):
            self._S[core.GEOM] += 1

    # -- learned state ------------------------------------------------------------------
    @property
    def n_cells(self) -> int:
        return int(self._S[core.SIZE]) if self._is_setup else 0

    @property
    def codebook_(self) -> np.ndarray:
        return self._V[: self.n_cells].copy()

    @property
    def q_(self) -> np.ndarray:
        return self._Q[: self.n_cells].copy()

    def _setup(self) -> None:
        self._allocate(min(self.max_cells, 256) + 4)
        self._pc[0, 0] = -1
        self._inv_scale[:] = 1.0 / self._scale
        params = self.get_params()
        pack_params(
            core.FloatParam,
            {
                **params,
                "alpha_now": 0.0,
                "epsilon_now": 0.0,
                "value_trigger": -1.0 if self.value_trigger is None else self.value_trigger,
                "reward_trigger": -1.0 if self.reward_trigger is None else self.reward_trigger,
            },
            out=self._P,
        )
        self._P[core.FloatParam.EPSILON_NOW] = episode_end.epsilon_at(self._P, self.num_episodes)
        self._P[core.FloatParam.ALPHA_NOW] = episode_end.alpha_at(self._P, self.num_episodes)
        pack_params(
            core.IntParam,
            {
                **params,
                "traces": self.traces == "replacing",
                "merge_pairs": core.MERGE_PAIRS.index(self.merge_pairs),
                "max_repeat": self.max_repeat or 0,
            },
            out=self._IP,
        )
        self._S[core.EPISODES] = self.num_episodes
        self._rec = np.zeros(N_R)
        self._spread = self._new_spread()
        self._direct: tuple = (None, None, None, None)  # see _advance

    def _begin_episode(self, obs: np.ndarray) -> None:
        x = self._as_obs(obs, 0)
        self._compiled(generic.generic_start, x, 0, 0.0)
        self._spread.add(x, start=True)

    def _end_episode(self) -> EpisodeRecord:
        if self._learns_metric:
            self._update_scale()  # (before the merge pass, which then sees the new metric)
        episode_end.end_episode(*self._state(), self._rec)  # type: ignore[call-arg]
        return episode_record(*self._rec)

    # -- the fused loop (avq.agents.avq_sarsa.fused) ------------------------------------------------
    def _fused_runner(self):
        # (The fused loops estimate no scale; the bounded mazes they run need none.)
        maze = _maze_loop.plan(self.env) if self.fused and not self._learns_metric else None
        if maze is None:
            return None
        mz = _maze_loop.maze_arguments(maze)
        loop = fused_loop(mz)

        def run(max_steps: int, max_episodes: int, max_records: int):
            steps, rows = _maze_loop.drive(
                maze,
                mz,
                loop,
                lambda: (core.Cells(*self._state()), self._rng),
                lambda: self._ensure_capacity(4),
                max_steps,
                max_episodes,
                max_records,
            )
            return steps, rows, bool(self._S[core.IN_EPISODE])

        return run

    # -- queries -----------------------------------------------------------------------------
    def cells(self, observations: np.ndarray) -> np.ndarray:
        """The cell index of each observation (a batch ``(b, n)``)."""
        if self.n_cells == 0:
            raise RuntimeError("AVQSarsa has no codebook yet; call learn() first")
        return self._codebook().nearest_batch(np.asarray(observations, dtype=np.float64))

    def _codebook(self) -> Codebook:
        """The current codebook as a :class:`Codebook` (a copy: geometry queries only)."""
        return Codebook.from_vectors(self._V[: self.n_cells], self._scale)

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        if self.n_cells == 0:
            return np.zeros(len(obs), dtype=np.int64)
        return self._Q[self.cells(obs)].argmax(axis=1).astype(np.int64)

    # -- saving ---------------------------------------------------------------------------------
    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        arrays.update(codebook=self.codebook_, q=self.q_, born=self._born[: self.n_cells].copy())  # (p, 2 + m)
        scale_meta, scale_arrays = self._metric_state(self._spread)
        meta.update(scale_meta)
        arrays.update(scale_arrays)
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        super()._load_state_dict(meta, arrays)
        codebook, q = arrays["codebook"], arrays["q"]
        n = self._V.shape[1]
        if codebook.ndim != 2 or codebook.shape[1] != n or q.shape != (codebook.shape[0], self.n_actions):
            raise ValueError(
                f"array shapes codebook {codebook.shape}, q {q.shape} do not fit ({n} dims, {self.n_actions} actions)"
            )
        born = arrays.get("born", np.zeros(len(q), dtype=np.int64))
        if born.shape == (len(q),):  # files from before the last-decision column: count every cell as just seen
            born = np.stack([born, np.full(len(q), self.num_episodes)], axis=1)
        if born.shape == (len(q), 2):  # files from before the decision counts: none counted
            born = np.concatenate([born, np.zeros((len(q), self.n_actions), dtype=np.int64)], axis=1)
        if born.shape != (len(q), 2 + self.n_actions):
            raise ValueError(f"array born has shape {born.shape}; expected ({len(q)}, {2 + self.n_actions})")
        self._load_metric_state(meta, arrays, self._spread)
        self._inv_scale[:] = 1.0 / self._scale
        p = len(q)
        self._ensure_capacity(p)
        self._V[:p], self._Q[:p], self._born[:p] = codebook, q, born
        self._S[core.SIZE] = p
        self._S[core.EPISODES] = self.num_episodes
        self._S[core.GEOM] += 1
        self._P[core.FloatParam.EPSILON_NOW] = episode_end.epsilon_at(self._P, self.num_episodes)
        self._P[core.FloatParam.ALPHA_NOW] = episode_end.alpha_at(self._P, self.num_episodes)
