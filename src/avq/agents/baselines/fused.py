"""Tabular Sarsa(λ) trained on a GridMaze inside one compiled loop (the shared driver:
:mod:`avq.agents._maze_loop`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from avq._numba import borrowed
from avq.agents._maze_loop import DONE, GO_ON, borrowed_grid_maze, budget_left, maze_move, maze_start
from avq.agents._td import SarsaParams, clear_traces, epsilon_greedy, table_step

__all__ = ["Table", "run_tabular_grid_maze"]


class Table(NamedTuple):
    """``tabular``'s table as the loop reads it: values, traces, active list, the row of each square
    (-1: none yet) and the square of each row, and the loop's integer and float state ``T``, ``TF``."""

    q: np.ndarray
    e: np.ndarray
    act: np.ndarray
    row_of: np.ndarray
    keys: np.ndarray
    T: np.ndarray
    TF: np.ndarray


@njit(cache=True, inline="always")
def _table_row(row_of, keys, T, x, y):
    """The table row of position (x, y), created (in order of first visit) when new."""
    r = row_of[y, x]
    if r < 0:
        r = T[0]
        row_of[y, x] = r
        keys[r, 0] = x
        keys[r, 1] = y
        T[0] += 1
        T[4] += 1
    return r


@njit(cache=True)
def run_tabular_grid_maze(table: Table, sp: SarsaParams, rng, env_rng, mz, pos, budget_steps, budget_episodes, rec):
    """Tabular Sarsa(λ) on a GridMaze: :func:`avq.agents._td.table_step` at every step, as ``TabularSarsa``
    does stepping the environment.

    ``T``: rows in use, current row, current action, episode steps, rows added this
    episode, in-episode flag; ``TF[0]``: episode return. ``q`` and ``e`` must have a
    row for every position; ``act`` is the active list of :mod:`avq.agents._td`.
    Returns ``(steps, episodes, status)``. (GridMaze only: ``mz.robot`` must be False.)
    """
    q, e, act, row_of, keys, T, TF = (
        borrowed(table.q),
        borrowed(table.e),
        borrowed(table.act),
        borrowed(table.row_of),
        borrowed(table.keys),
        borrowed(table.T),
        borrowed(table.TF),
    )
    mz, pos, rec = borrowed_grid_maze(mz), borrowed(pos), borrowed(rec)
    steps = 0
    episodes = 0
    while True:
        if T[5] == 0:
            status = budget_left(steps, episodes, budget_steps, budget_episodes, rec)
            if status != GO_ON:
                return steps, episodes, status
            maze_start(env_rng, pos, mz)
            clear_traces(e, act)
            T[3] = 0
            T[4] = 0
            TF[0] = 0.0
            T[1] = _table_row(row_of, keys, T, int(pos[0]), int(pos[1]))
            T[2] = epsilon_greedy(rng, q, T[1], sp.epsilon)
            T[5] = 1
        if steps >= budget_steps:
            return steps, episodes, DONE
        r, terminated, _ = maze_move(env_rng, pos, T[2], mz)
        truncated = pos[2] >= mz.max_episode_steps
        steps += 1
        T[3] += 1
        TF[0] += r
        s2 = _table_row(row_of, keys, T, int(pos[0]), int(pos[1]))
        T[2] = table_step(rng, q, e, act, T[1], T[2], r, s2, terminated, sp)
        T[1] = s2
        if terminated or truncated:
            T[5] = 0
            rec[episodes, 0] = T[3]
            rec[episodes, 1] = TF[0]
            rec[episodes, 2] = T[0]
            rec[episodes, 3] = T[4]
            rec[episodes, 4] = 0
            rec[episodes, 5] = 0
            rec[episodes, 6] = T[3]
            episodes += 1
