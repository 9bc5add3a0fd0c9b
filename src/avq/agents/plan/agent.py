"""AVQ with a learned model of its cells and planning over it (``avq-plan``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from avq._numba import Compiled, direct_call
from avq._validate import PlanningSettings, check_bool, check_int, check_optional, check_planning_params, check_range
from avq.agents import _maze_loop
from avq.agents._params import pack_params
from avq.agents._spaces import ScaledMetric
from avq.agents.base import EpisodeRecord, episode_record
from avq.agents.plan import kernels as core, memory, model as _model, resolution
from avq.agents.plan.fused import run_plan_maze
from avq.agents.plan.state import (
    ACTION,
    EP_STEPS,
    GEOM,
    IN_EPISODE,
    MEM_N,
    N_F,
    N_S,
    SIZE,
    PlanArrays,
    PlanIntParam,
    PlanParam,
    auto_v_opt,
    best_return_to_go,
    horizon,
    load_cells,
    load_state_arrays,
    no_neighbours,
    value_ceiling,
)
from avq.agents.plan.sweeping import ModelPlanner
from avq.quantizer import Codebook

__all__ = ["PlanningAVQ"]


class PlanningAVQ(ScaledMetric, PlanningSettings, ModelPlanner):
    """AVQ that learns a model of its cells and plans over it by prioritized sweeping.

    It acts as AVQ does: one decision per cell of a growing codebook, repeated until the cell
    changes, a collision, or the end of the episode (docs: explanation/paper.md, Acting). Each such
    aggregate transition is recorded in a model of the cells (successor counts, mean return and discount, so one
    decision is an SMDP step), and the values are planned from the model by prioritized sweeping
    with ``n_backups`` backups per transition (src/avq/agents/plan/model.py). Pairs of a cell and an
    action tried fewer than ``known_after`` times are worth ``v_opt``, so the agent tries each
    decision of each cell: it explores coarse to fine. Cells grow by the paper's collision rule
    and where a decision's outcome disagrees with the model (src/avq/agents/plan/kernels.py).

    Args:
        env: A Gymnasium environment (or registered id) with a ``Box`` observation space and
            ``Discrete`` actions.
        gamma, epsilon, v_opt, v_min, known_after, n_backups, tol: the planner's, as in
            :class:`avq.agents.sweeping.PrioritizedSweeping`; and ``v_opt="auto"``, R-max's bound for a task
            whose rewards are not known beforehand: the episode's horizon (the environment's time limit;
            without one ``1 / (1 - gamma)``, or 1,000 steps with ``gamma = 1``) times the largest reward seen
            so far, or 0 while no reward > 0 has been seen; and 0 once a reward below 0 has been seen as well
            (shaped rewards: :func:`avq.agents.plan.state.auto_v_opt`), every planned value then no higher than
            the largest return seen from any step to an episode's end
            (:func:`avq.agents.plan.state.value_ceiling`). Brought up to date at the end of every episode (the
            pairs not yet known and their predecessors are backed up again). ``v_opt_`` is the value in force.
        d_min: Minimum resolution (scaled units): no vector is appended within ``d_min`` of another.
        collision_growth: The paper's growth: on a collision farther than ``d_min`` from the cell's
            vector, append the observation (docs: explanation/paper.md, Growing).
        collision_cut: Growth on collisions for more than two dimensions, instead of ``collision_growth``
            (whose appended observations tile walls of ``n - 1`` dimensions; give ``collision_growth=False``): a
            decision that collides at ``x`` in a cell from which it was also seen to leave without a collision
            cuts the cell across one axis, the one on which ``x`` and the mean start of the decision's most
            frequent other successor differ most (scaled); the cell's vector moves along that axis alone to each.
        outcome_split: Split a cell where a decision's outcomes disagree beyond ``split_threshold`` plus what their
            starts' distance explains, each ending in a settled cell ("unsettled": or in one owing no optimism).
        split_threshold: That excess, > 0.
        axis_share: The outcome split cuts across one axis alone (as ``collision_cut``) where it carries at least
            this share, in [0, 1], of the squared scaled gap between the groups' mean starts; None: their bisector.
        cycle_split: When two decisions lead from a cell to another and straight back, give the square
            of the return a cell of its own (as ``AVQSarsa``'s ``cycle_split``).
        value_slope: The value's slope ``L`` of that rule, per unit of scaled distance; None: estimated
            online (the mean return per scaled distance travelled by the transitions without collision).
        memory: Aggregate transitions remembered, from which the model follows the cells as they
            change (the oldest is forgotten beyond it).
        scale: Per-dimension scale of the metric. ``"auto"`` (the default), as :class:`avq.agents.AVQSarsa`'s:
            ``high - low`` of the bounds where they are finite, and where they are not an estimate from the
            first ``scale_warmup`` observations (``AUTO_SCALE_STDS`` standard deviations), brought up to date
            at the end of every episode until then; the model then follows its remembered transitions into
            the cells of the new metric. A number or one per dimension: that scale. None: ``high - low`` of
            the observation bounds, every one of which must be finite. ``"spread"``: every dimension is estimated
            from the observations, even where the bounds are finite (their range is used only until the first
            episode ends); a dimension that ``obs_bounds`` bounds keeps that range. For tasks whose bounds are far
            wider than what a run visits (Acrobot's velocities).
        scale_warmup: With ``scale="auto"`` or ``"spread"``: the observations from which the scale is estimated, >= 2.
        scale_factor: A number or one per dimension (each > 0) by which the metric's scale is multiplied,
            whatever its source (``scale``, the bounds, or the estimate of ``"auto"`` and ``"spread"``): a
            dimension of factor 2 counts half as much in the distance, so its cells are twice as wide. For a
            task whose decisions depend more on some dimensions than on others (Acrobot's velocities).
        obs_bounds: Instead of ``scale``: ``(low, high)`` per dimension (None keeps the space's).
        ignore_noise: With ``scale="auto"`` or ``"spread"``: once ``scale_warmup`` observations are counted, a
            dimension that the observation before does not predict (drawn afresh each step: ``avq.agents._noise``),
            or whose change it does not (a slow drift), gets an infinite scale, so the distance and the cells ignore
            it; a drifting one gets its scale back if, after 30,000 observations, it is found to matter.
        reweight_when_full: Once the codebook holds ``max_cells``, at the end of the first episode at which three
            quarters of the cells (and at least 20) have every decision known: weight each dimension of the metric by
            the slope of those cells' planned values along it, finer where the value changes fast, once
            (src/avq/agents/_value_weights.py); the model follows its transitions into the cells of the new metric.
        finer_when_settled: How many times, at most, the floor of the growth from decisions (``split_after``, the
            outcome split) halves from ``d_min``, each when 90% of the cells (and 20) have every decision known at an
            episode's end (src/avq/agents/plan/resolution.py). 0: it stays ``d_min``.
        max_cells: Upper bound on the codebook size; growth past it is refused (counted in ``refused``).
        split_after: Growth for tasks without collisions: a decision that has stayed this many steps in its cell,
            at an observation farther than ``d_min`` from every vector, ends there, and that observation becomes a
            cell of its own (so a cell is at most about ``split_after`` steps across where the agent goes, down to
            ``d_min``; refused growth is counted once per decision). None: off (a decision lasts until the cell
            changes). On a task without collisions and with it off, the agent keeps its first cell.
        rho: Merging (the paper's, under the model: src/avq/agents/plan/merge.py): at the end of an episode,
            two cells whose decisions are all known and whose action-value profiles differ by a mean square
            below ``rho`` merge, the pair chosen among each cell's ``merge_neighbours`` nearest; the model of
            the merged cell is composed from its halves' remembered transitions (a decision that ended at the
            old border goes on), and the outcome split may cut it again. None: no merging. Merging stops once
            the memory is full (it rebuilds the model from what the memory holds).
        merge_neighbours: How many of a cell's nearest cells may be its partner in a merge, >= 1.
        merge_same_action: Merge only cells whose greedy actions agree (as ``AVQSarsa``'s): a decision that crossed
            from one into the other then goes on as it would have been taken again: the greedy policy goes as before.
        compose_crossings: A transition that ended only because its cell changed, its ends now in one cell (a cut, the
            metric changed), goes on as under a merge instead of ending in its own cell. Always on with ``rho``.
            ``"noise"`` (the default): only the transitions remembered when the noise test leaves dimensions out of
            the metric; where it finds no noise, as ``False``.
        known_radius: While learning, a decision never tried from within this scaled distance of the current
            observation (from the mean start of each of its successors' transitions) is worth at least ``v_opt`` for
            that decision (src/avq/agents/plan/explore.py). None: off (known wherever in its cell it was tried).
        fused: On ``avq/GridMaze-v0`` and ``avq/RobotMaze-v0`` with noise-free sonar (standard wrappers only), run
            maze and agent in one compiled loop: the same results, faster. False: step the environment from Python.
        seed: Seed of every random choice the agent makes and of the environment's first reset.

    The signature's defaults are those of ``avq`` (and ``avq-plan``) on tasks without collisions; on the mazes
    ``make_agent`` gives the maze settings (``avq/agents/defaults/avq-plan.yaml``).

    Attributes:
        codebook_: ``(p, n)`` codebook vectors.
        q_: ``(p, m)`` planned values of the cells' decisions (``v_opt`` where not yet known).
        n_cells: ``p``.
        backups_: backups done so far; ``queued_``: cells waiting in the planner's queue.
    """

    _transient: ClassVar[dict[str, Any]] = {"_direct": None}

    def __init__(
        self,
        env: gym.Env | str,
        *,
        gamma: float = 1.0,
        epsilon: float = 0.0,
        v_opt: float | str = "auto",
        v_min: float = -10_000.0,
        known_after: int = 2,
        n_backups: int = 100,
        tol: float = 0.01,
        d_min: float = 0.05,
        collision_growth: bool = True,
        collision_cut: bool = False,
        outcome_split: bool | str = True,
        cycle_split: bool = False,
        split_threshold: float = 10.0,
        axis_share: float | None = None,
        value_slope: float | None = None,
        memory: int = 100_000,
        scale: float | Sequence[float] | str | None = "auto",
        scale_warmup: int = 1000,
        scale_factor: float | Sequence[float] = 1.0,
        obs_bounds: Sequence[Sequence[float] | None] | None = None,
        ignore_noise: bool = True,
        reweight_when_full: bool = True,
        finer_when_settled: int = 1,
        max_cells: int = 2048,
        split_after: int | None = 5,
        rho: float | None = None,
        merge_neighbours: int = 3,
        merge_same_action: bool = True,
        compose_crossings: bool | str = "noise",
        known_radius: float | None = None,
        fused: bool = True,
        seed: int | None = None,
    ) -> None:
        check_planning_params(self, gamma, epsilon, v_opt, v_min, known_after, n_backups, tol, auto_v_opt=True)
        self.d_min = check_range("d_min", d_min, 0.0, np.inf, high_open=True)
        self.collision_growth = check_bool("collision_growth", collision_growth)
        self.collision_cut = check_bool("collision_cut", collision_cut)
        if self.collision_growth and self.collision_cut:
            raise ValueError(
                "collision_growth=True and collision_cut=True are two answers to a collision; give "
                "collision_growth=False to cut cells across one axis at collisions instead of appending them"
            )
        self.outcome_split = check_bool("outcome_split", outcome_split, "unsettled")
        self.cycle_split = check_bool("cycle_split", cycle_split)
        self.split_threshold = check_range(
            "split_threshold", split_threshold, 0.0, np.inf, low_open=True, high_open=True
        )
        self.axis_share = check_optional(check_range, "axis_share", axis_share, 0.0, 1.0)
        self.value_slope = check_optional(check_range, "value_slope", value_slope, 0.0, np.inf, high_open=True)
        self.memory = check_int("memory", memory, 1)
        self.max_cells = check_int("max_cells", max_cells, 1)
        self.finer_when_settled = check_int("finer_when_settled", finer_when_settled, 0)
        self.split_after = check_optional(check_int, "split_after", split_after, 1)
        self.rho = check_optional(check_range, "rho", rho, 0.0, np.inf, high_open=True)
        self.merge_neighbours = check_int("merge_neighbours", merge_neighbours, 1)
        self.merge_same_action = check_bool("merge_same_action", merge_same_action)
        self.compose_crossings = check_bool("compose_crossings", compose_crossings, "noise")
        self.known_radius = check_optional(check_range, "known_radius", known_radius, 0.0, np.inf, high_open=True)
        self.fused = check_bool("fused", fused)
        super().__init__(env, seed, scale, scale_warmup, scale_factor, obs_bounds, ignore_noise, reweight_when_full)
        #: v_opt="auto": the horizon by which the largest reward seen is multiplied.
        self._horizon = horizon(self.env, self.gamma)

    # -- learned state ------------------------------------------------------------------
    @property
    def n_cells(self) -> int:
        return int(self._ag.S[SIZE]) if self._is_setup else 0

    @property
    def codebook_(self) -> np.ndarray:
        return self._ag.V[: self.n_cells].copy()

    @property
    def v_opt_(self) -> float:
        """What an untried decision is worth now (``v_opt``, or with ``"auto"`` its value so far)."""
        return (
            float(self._model.a.MP[_model.ModelParam.V_OPT])
            if self._is_setup
            else (0.0 if self.v_opt == "auto" else float(self.v_opt))
        )

    def _setup(self) -> None:
        n, cap = len(self._scale), min(self.max_cells, 256) + core.APPENDS_PER_STEP
        held = memory.HELD if self.compose_crossings == "noise" else 0  # (remembered, composed on noise)
        values = dict(
            self.get_params(),
            outcome_split=core.UNSETTLED if self.outcome_split == "unsettled" else int(self.outcome_split),
            value_slope=-1.0 if self.value_slope is None else self.value_slope,
            split_after=0 if self.split_after is None else self.split_after,
            rho=-1.0 if self.rho is None else self.rho,
            known_radius=-1.0 if self.known_radius is None else self.known_radius,
            axis_share=-1.0 if self.axis_share is None else self.axis_share,
            compose_crossings=memory.COMPOSED if self.compose_crossings is True or self.rho is not None else held,
        )
        #: The agent's arrays as its kernels take them (avq.agents.plan.state); the model's are self._model.a.
        self._ag = PlanArrays(
            V=np.zeros((cap, n)),
            inv_scale=1.0 / self._scale,
            P=pack_params(PlanParam, values),
            IP=pack_params(PlanIntParam, values, dtype=np.int64),
            S=np.zeros(N_S, dtype=np.int64),
            F=np.zeros(N_F + n + 1),
            xs=np.zeros(n),
            mem_x=np.zeros((self.memory, 2 * n)),
            mem_i=np.zeros((self.memory, 4), dtype=np.int64),
            mem_f=np.zeros((self.memory, 2)),
            e_xs=np.zeros((0, n)),
            near=no_neighbours(cap, self.merge_neighbours),
        )
        self._model = _model.Model(
            self.n_actions, 0.0 if isinstance(self.v_opt, str) else self.v_opt, self.v_min, self.known_after, self.tol
        )
        #: The largest and smallest rewards seen, the largest return to an episode's end from any of its steps,
        #: and the current episode's rewards (v_opt="auto").
        self._r_max, self._r_min, self._to_go_max = -np.inf, np.inf, -np.inf
        self._ep_rewards: list[float] = []
        self._spread = self._new_spread()
        #: The compiled core.step for the argument types of the last step that went through Numba's
        #: dispatcher (see _advance), or None.
        self._direct = None
        #: The fused loop for each maze's types (see _fused_runner).
        self._loops: dict[tuple, Compiled] = {}

    def _make_room(self) -> None:
        """Room for the cells and edges one step may add (the kernels never reallocate). A reallocated array
        has the dtype, dimensions and layout of the one it replaces, so the records keep their types."""
        ag = self._ag
        size, cap = int(ag.S[SIZE]), ag.V.shape[0]
        if size + core.APPENDS_PER_STEP > cap:
            new = np.zeros((max(2 * cap, size + core.APPENDS_PER_STEP), ag.V.shape[1]))
            new[:cap] = ag.V
            ag = self._ag = ag._replace(V=new, near=no_neighbours(len(new), self.merge_neighbours))
        self._model.reserve(states=core.APPENDS_PER_STEP, edges=core.APPENDS_PER_STEP * (int(ag.S[MEM_N]) + 1))
        edges = self._model.a.e_to.shape[0]
        if ag.e_xs.shape[0] < edges:
            grown = np.zeros((edges, ag.e_xs.shape[1]))
            grown[: len(ag.e_xs)] = ag.e_xs
            self._ag = ag._replace(e_xs=grown)

    # -- the episode loop -----------------------------------------------------------------
    def _begin_episode(self, obs: Any) -> None:
        x = self._as_obs(obs, 0)
        self._make_room()
        self._draws.reserve()
        if core.start(self._ag, self._model.a, self._draws.src, x) == core.NOT_FINITE:
            self._refuse_non_finite(obs, 0.0, 0)
        self._spread.add(x, start=True)

    def _as_obs(self, obs: Any, step: int) -> np.ndarray:
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != self._ag.xs.shape:
            raise ValueError(f"observation at step {step} has shape {x.shape}; the space says {self._ag.xs.shape}")
        return x

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        # One compiled call per step (core.step); after the first through Numba's dispatcher, later ones call the
        # function it chose (avq._numba.direct_call), which skips typing the records: their types stay (_make_room,
        # Model.reserve; x a float64 vector, r a float); an x not writable and C-contiguous goes through the dispatcher.
        env_step, S, draws, model, kernel = self.env.step, self._ag.S, self._draws, self._model, core.step
        direct = self._direct
        count = None if self._spread.done else self._spread.add  # (during the warm-up, and its log)
        r_max, r_min = self._r_max, self._r_min
        keep = self._ep_rewards.append if self.v_opt == "auto" else None  # (only "auto" reads them)
        a = int(S[ACTION])
        n = 0
        while n < max_steps:
            obs, r, terminated, truncated, info = env_step(taken := a)
            n += 1
            x = self._as_obs(obs, int(S[EP_STEPS]) + 1)
            try:
                r = float(r)
            except (TypeError, ValueError):
                raise ValueError(
                    f"reward {r!r} at step {int(S[EP_STEPS]) + 1} of episode {self.num_episodes + 1} is not a number"
                ) from None
            self._make_room()
            draws.reserve()
            collided = bool(info.get("collision", False))
            args = (self._ag, model.a, draws.src, x, r, collided, bool(terminated), bool(truncated))
            flags = x.flags
            if direct is not None and flags.c_contiguous and flags.writeable:
                a = direct(*args)
            else:
                a = kernel(*args)
                if flags.c_contiguous and flags.writeable:
                    direct = self._direct = direct_call(kernel, args)
            if a == core.NOT_FINITE:
                self._refuse_non_finite(obs, r, int(S[EP_STEPS]) + 1)
            if count is not None and not count(x, False, taken, r):
                count = None
            if r > r_max:
                r_max = self._r_max = r
            if r < r_min:
                r_min = self._r_min = r
            if keep is not None:
                keep(r)
            if a == core.ENDED:
                return n, True
        return n, False

    def _end_episode(self) -> EpisodeRecord:
        if self._refresh_metric(self._spread, self._ag.inv_scale, self.n_cells >= self.max_cells):
            # The metric changed (scale="auto", the noise test, reweight_when_full): the model follows the remembered
            # transitions into their cells (vectors in observation units), composing held crossings once noise is out.
            memory.relocate(self._ag, self._model.a, -1, -1, bool(np.isinf(self._scale).any()))
            self._ag.S[GEOM] += 1
        if self.v_opt == "auto":
            self._to_go_max = max(self._to_go_max, best_return_to_go(self._ep_rewards, self.gamma))
            ceiling = value_ceiling(self._r_min, self._r_max, self._to_go_max)
            self._model.set_optimism(auto_v_opt(self._horizon, self._r_min, self._r_max), ceiling)
        self._ep_rewards = []
        row = np.zeros(7)
        core.end_record(self._ag.S, self._ag.F, row)
        return episode_record(*row)

    def _settled_values(self) -> tuple[np.ndarray, np.ndarray, int]:
        n, settled = self.n_cells, np.zeros(self.n_cells, dtype=np.bool_)
        resolution.settled_cells(self._model.a, n, settled)
        values = self._model.a.Q[:n].max(axis=1)
        settled &= values > self.v_min
        return self._ag.V[:n][settled], values[settled], n

    # -- the fused loop (avq.agents.plan.fused) ------------------------------------------------
    def _fused_runner(self):
        # (The fused loops estimate no scale and see no rewards in Python, which v_opt="auto" reads.)
        fusable = self.fused and not self._learns_metric and self.v_opt != "auto"
        maze = _maze_loop.plan(self.env) if fusable else None
        if maze is None:
            return None
        # (called once per learn() or episode: directly after the first call, for this maze's types)
        mz = _maze_loop.maze_arguments(maze)
        loop = self._loops.setdefault(_maze_loop.maze_types(mz), Compiled(run_plan_maze))

        def run(max_steps: int, max_episodes: int, max_records: int):
            steps, rows = _maze_loop.drive(
                maze,
                mz,
                loop,
                lambda: (self._ag, self._model.a, self._rng),
                self._make_room,
                max_steps,
                max_episodes,
                max_records,
            )
            return steps, rows, bool(self._ag.S[IN_EPISODE])

        return run

    # -- queries -----------------------------------------------------------------------------
    def cells(self, observations: np.ndarray) -> np.ndarray:
        """The cell index of each observation (a batch ``(b, n)``)."""
        if self.n_cells == 0:
            raise RuntimeError("PlanningAVQ has no codebook yet; call learn() first")
        return Codebook.from_vectors(self._ag.V[: self.n_cells], self._scale).nearest_batch(
            np.asarray(observations, dtype=np.float64)
        )

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        if self.n_cells == 0:
            return np.zeros(len(obs), dtype=np.int64)
        return self._greedy_q()[self.cells(obs)].argmax(axis=1).astype(np.int64)

    # -- saving ---------------------------------------------------------------------------------
    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        meta, arrays = super()._state_dict()
        ag = self._ag
        arrays.update({name: getattr(ag, name).copy() for name in ("S", "F", "xs", "mem_x", "mem_i", "mem_f")})
        arrays.update(codebook=self.codebook_, e_xs=ag.e_xs[: int(self._model.a.C[_model.N_EDGES])].copy())
        arrays.update(self._model.state_dict())
        scale_meta, scale_arrays = self._metric_state(self._spread)
        meta.update(
            scale_meta,
            reward_max=None if self._r_max == -np.inf else self._r_max,
            reward_min=None if self._r_min == np.inf else self._r_min,
            return_to_go_max=None if self._to_go_max == -np.inf else self._to_go_max,
        )
        arrays["episode_rewards"] = np.asarray(self._ep_rewards, dtype=np.float64)
        arrays.update(scale_arrays)
        return meta, arrays

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        super()._load_state_dict(meta, arrays)
        load_state_arrays(self._ag, arrays)
        codebook = arrays["codebook"]
        if codebook.shape != (size := int(self._ag.S[SIZE]), n := self._ag.xs.shape[0]):
            raise ValueError(f"array codebook has shape {codebook.shape}; expected ({size}, {n})")
        self._model.load_state_dict(arrays)
        self._make_room()  # (room for the loaded cells and edges)
        load_cells(self._ag, codebook, arrays["e_xs"], int(self._model.a.C[_model.N_EDGES]))
        self._load_metric_state(meta, arrays, self._spread)
        self._r_max = -np.inf if meta.get("reward_max") is None else float(meta["reward_max"])
        self._r_min = np.inf if meta.get("reward_min") is None else float(meta["reward_min"])
        self._to_go_max = -np.inf if meta.get("return_to_go_max") is None else float(meta["return_to_go_max"])
        self._ep_rewards = [float(r) for r in arrays.get("episode_rewards", ())]
        self._ag.inv_scale[:] = 1.0 / self._scale
