"""The model-based agents trained on a built-in maze inside one compiled loop: ``avq-plan``
(:func:`run_plan_maze`) and ``tabular-ps`` (:func:`run_ps_grid_maze`). The shared driver:
:mod:`avq.agents._maze_loop`.

Each loop borrows every array it is given (:func:`avq._numba.borrowed`): it rebuilds the records
(:class:`~avq.agents.plan.state.PlanArrays`, :class:`~avq.agents.plan.model.ModelArrays`,
:class:`PSTable`, :class:`~avq.agents._maze_loop.Maze`) from borrowed views, so that handing them
on to the kernels counts no references; ``avq-plan``'s loop borrows the generators and its own arrays
(:class:`Work`) too, as AVQ Sarsa's does (:mod:`avq.agents.avq_sarsa.fused`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from avq._numba import borrowed, borrowed_record
from avq.agents._maze_loop import (
    DONE,
    GO_ON,
    NEED_CAPACITY,
    Maze,
    NearestCache,
    borrowed_grid_maze,
    borrowed_maze,
    budget_left,
    cached_nearest,
    maze_move,
    maze_observation,
    maze_start,
    nearest_cache,
)
from avq.agents._td import epsilon_greedy
from avq.agents.plan import kernels as plan_core, model as _model
from avq.agents.plan.model import ModelArrays, borrowed_model
from avq.agents.plan.state import ACTION, GEOM, IN_EPISODE, SIZE, PlanArrays, borrowed_plan
from avq.agents.plan.tabular import ps_step
from avq.quantizer import nearest_index

__all__ = ["run_plan_maze", "run_ps_grid_maze", "PSTable", "Work"]

# T: the episode of tabular-ps's fused loop (int): current row, current action, episode steps, rows added this
# episode, in-episode flag
T_ROW, T_ACTION, T_STEPS, T_NEW, T_IN_EPISODE = range(5)
N_T = 5


class PSTable(NamedTuple):
    """``tabular-ps``'s table on a GridMaze, as its fused loop reads and writes it."""

    #: ``(h, w)`` the state of each square (-1: not visited yet).
    row_of: np.ndarray
    #: ``(h * w, 2)`` the square ``(x, y)`` of each state.
    keys: np.ndarray
    #: The episode (indices ``T_*``).
    T: np.ndarray
    #: ``TF[0]``: the episode's return.
    TF: np.ndarray


class Work(NamedTuple):
    """``avq-plan``'s loop's own arrays, made once per call: the observation, the sonar ranges, and on GridMaze
    the nearest cell of every square."""

    x: np.ndarray
    sonar: np.ndarray
    near: NearestCache


@njit(cache=True)
def run_plan_maze(ag: PlanArrays, m: ModelArrays, rng, env_rng, mz: Maze, pos, budget_steps, budget_episodes, rec):
    """Train ``avq-plan`` on a maze: :func:`avq.agents.plan.kernels.start` and ``step`` at every step, as
    ``PlanningAVQ`` does stepping the environment. On GridMaze the nearest cell of every square is kept
    while the codebook does not change (:func:`~avq.agents._maze_loop.cached_nearest`). Returns
    ``(steps, episodes, status)``; ``NEED_CAPACITY`` when the arrays may not hold what the next step adds."""
    work = Work(np.empty(ag.V.shape[1]), np.empty(mz.dirs.shape[0]), nearest_cache(mz))
    return _train_plan(ag, m, work, rng, env_rng, mz, pos, budget_steps, budget_episodes, rec)  # (holds work)


@njit(cache=True)
def _train_plan(
    ag: PlanArrays, m: ModelArrays, work: Work, rng, env_rng, mz: Maze, pos, budget_steps, budget_episodes, rec
):
    """:func:`run_plan_maze`'s loop, on borrowed views of everything it is given."""
    ag, m = borrowed_plan(ag), borrowed_model(m)
    x, sonar = borrowed(work.x), borrowed(work.sonar)
    near, near_d2, near_seen = borrowed_record(work.near)
    rng, env_rng = borrowed(rng), borrowed(env_rng)
    mz, pos, rec = borrowed_maze(mz), borrowed(pos), borrowed(rec)
    V, inv_scale, S = ag.V, ag.inv_scale, ag.S
    steps = 0
    episodes = 0
    while True:
        if not plan_core.room_left(ag, m) or ag.e_xs.shape[0] < m.e_to.shape[0]:
            return steps, episodes, NEED_CAPACITY
        if S[IN_EPISODE] == 0:
            status = budget_left(steps, episodes, budget_steps, budget_episodes, rec)
            if status != GO_ON:
                return steps, episodes, status
            maze_start(env_rng, pos, mz)
            maze_observation(x, pos, mz, sonar)
            plan_core.start(ag, m, rng, x)
            continue
        if steps >= budget_steps:
            return steps, episodes, DONE
        r, terminated, collision = maze_move(env_rng, pos, S[ACTION], mz)
        truncated = pos[2] >= mz.max_episode_steps
        maze_observation(x, pos, mz, sonar)
        steps += 1
        if mz.robot:
            j, d2 = nearest_index(V, S[SIZE], x, inv_scale)
        else:
            j, d2 = cached_nearest(near, near_d2, near_seen, V, S[SIZE], S[GEOM], x, inv_scale, pos)
        if plan_core.goes_on(ag, r, j, d2, collision, terminated or truncated):
            continue
        a = plan_core.end_transition(ag, m, rng, x, collision, terminated, truncated, j, d2)
        if a == plan_core.ENDED:
            plan_core.end_record(S, ag.F, rec[episodes])
            episodes += 1


@njit(cache=True, inline="always")
def _borrowed_table(table: PSTable) -> PSTable:
    return PSTable(borrowed(table.row_of), borrowed(table.keys), borrowed(table.T), borrowed(table.TF))


@njit(cache=True, inline="always")
def _no_room(m: ModelArrays) -> bool:
    """Whether the model may not hold a new state and a new edge."""
    return m.C[_model.N_STATES] + 1 > m.cnt.shape[0] or m.C[_model.N_EDGES] + 1 > m.e_to.shape[0]


@njit(cache=True)
def run_ps_grid_maze(
    m: ModelArrays,
    table: PSTable,
    gamma,
    epsilon,
    n_backups,
    rng,
    env_rng,
    mz: Maze,
    pos,
    budget_steps,
    budget_episodes,
    rec,
):
    """Prioritized sweeping (``tabular-ps``) on a GridMaze: a state for every position on its first visit and
    :func:`avq.agents.plan.tabular.ps_step` at every step, as ``PrioritizedSweeping`` does stepping the
    environment. Returns ``(steps, episodes, status)``; ``NEED_CAPACITY`` when the model may not hold a new
    state and a new edge."""
    m, table = borrowed_model(m), _borrowed_table(table)
    mz, pos, rec = borrowed_grid_maze(mz), borrowed(pos), borrowed(rec)
    row_of, keys, T, TF = table.row_of, table.keys, table.T, table.TF  # (written: see the note on ModelArrays)
    steps = 0
    episodes = 0
    while True:
        if _no_room(m):
            return steps, episodes, NEED_CAPACITY
        if T[T_IN_EPISODE] == 0:
            status = budget_left(steps, episodes, budget_steps, budget_episodes, rec)
            if status != GO_ON:
                return steps, episodes, status
            maze_start(env_rng, pos, mz)
            T[T_STEPS] = 0
            T[T_NEW] = 0
            TF[0] = 0.0
            T[T_ROW] = _ps_row(row_of, keys, T, m, int(pos[0]), int(pos[1]))
            T[T_ACTION] = epsilon_greedy(rng, m.Q, T[T_ROW], epsilon)
            T[T_IN_EPISODE] = 1
            continue
        if steps >= budget_steps:
            return steps, episodes, DONE
        r, terminated, _ = maze_move(env_rng, pos, T[T_ACTION], mz)
        truncated = pos[2] >= mz.max_episode_steps
        steps += 1
        T[T_STEPS] += 1
        TF[0] += r
        s2 = _ps_row(row_of, keys, T, m, int(pos[0]), int(pos[1]))
        T[T_ACTION] = ps_step(m, rng, T[T_ROW], T[T_ACTION], r, gamma, s2, terminated, epsilon, n_backups)
        T[T_ROW] = s2
        if terminated or truncated:
            T[T_IN_EPISODE] = 0
            rec[episodes, 0] = T[T_STEPS]
            rec[episodes, 1] = TF[0]
            rec[episodes, 2] = m.C[_model.N_STATES]
            rec[episodes, 3] = T[T_NEW]
            rec[episodes, 4] = 0
            rec[episodes, 5] = 0
            rec[episodes, 6] = T[T_STEPS]
            episodes += 1
            if _no_room(m):
                return steps, episodes, NEED_CAPACITY


@njit(cache=True, inline="always")
def _ps_row(row_of, keys, T, m: ModelArrays, x, y):
    """The state of position (x, y), made (in order of first visit) when new (the arrays of a :class:`PSTable`)."""
    r = row_of[y, x]
    if r < 0:
        r = _model.add_state(m)
        row_of[y, x] = r
        keys[r, 0] = x
        keys[r, 1] = y
        T[T_NEW] += 1
    return r
