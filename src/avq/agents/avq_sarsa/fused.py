"""AVQ Sarsa(λ) trained on a built-in maze inside one compiled loop (the shared driver:
:mod:`avq.agents._maze_loop`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from avq._numba import borrowed
from avq.agents._maze_loop import (
    DONE,
    NEED_CAPACITY,
    RECORDS_FULL,
    borrowed_maze,
    maze_move,
    maze_observation,
    maze_start,
)
from avq.agents.avq_sarsa.episode_end import end_episode
from avq.agents.avq_sarsa.kernels import (
    ACTION,
    GEOM,
    IN_EPISODE,
    SIZE,
    Cells,
    Params,
    Step,
    begin_episode,
    decide,
    learn,
    observe,
    observe_at,
)
from avq.quantizer import nearest_index

__all__ = ["run_avq_maze"]


@njit(cache=True)
def run_avq_maze(cells: Cells, rng, env_rng, mz, pos, budget_steps, budget_episodes, rec):
    """Train AVQ Sarsa(λ) on a maze for at most ``budget_steps`` steps and ``budget_episodes`` episodes.

    ``cells`` holds the agent's arrays, ``mz`` the maze (:class:`~avq.agents._maze_loop.Maze`); ``pos`` holds the robot's ``x, y`` and
    the steps taken in the current episode. On GridMaze, the nearest cell of every square is kept
    while the codebook does not change. Returns ``(steps, episodes, status)``.
    """
    # (Taken out of the record once: the kernels take the arrays one by one. Under Numba 0.68 an inlined
    # kernel that writes through a record argument can lose those writes in this loop.)
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F = (
        borrowed(cells.V),
        borrowed(cells.Q),
        borrowed(cells.E),
        borrowed(cells.born),
        borrowed(cells.act),
        borrowed(cells.pc),
        borrowed(cells.inv_scale),
        borrowed(cells.P),
        borrowed(cells.IP),
        borrowed(cells.S),
        borrowed(cells.F),
    )
    mz, pos, rec = borrowed_maze(mz), borrowed(pos), borrowed(rec)
    par = Params(P, IP, inv_scale)  # (read only: the kernels write the arrays they take one by one)
    cap = V.shape[0]
    scr = np.empty((1, Q.shape[1]))  # bonus values of one cell (count-based exploration)
    steps = 0
    episodes = 0
    cache_shape = (1, 1) if mz.robot else mz.walls.shape
    cell_cache = np.full(cache_shape, -1, dtype=np.int64)
    dist_cache = np.zeros(cache_shape)
    cache_geom = -1
    x = np.empty(V.shape[1])
    sonar = np.empty(mz.dirs.shape[0])
    while True:
        if S[IN_EPISODE] == 0:
            if steps >= budget_steps or episodes >= budget_episodes:
                return steps, episodes, DONE
            if episodes >= rec.shape[0]:
                return steps, episodes, RECORDS_FULL
            if S[SIZE] + 1 > cap:
                return steps, episodes, NEED_CAPACITY
            maze_start(env_rng, pos, mz)
            maze_observation(x, pos, mz, sonar)
            cell = begin_episode(V, Q, E, born, act, S, F, par, x)
            S[ACTION] = decide(rng, Q, born, P, cell, scr)
        if steps >= budget_steps:
            return steps, episodes, DONE
        if S[SIZE] + 3 > cap:
            return steps, episodes, NEED_CAPACITY
        a = S[ACTION]
        r, terminated, collision = maze_move(env_rng, pos, a, mz)
        truncated = pos[2] >= mz.max_episode_steps
        maze_observation(x, pos, mz, sonar)
        steps += 1
        st = Step(x, r, collision, terminated, terminated or truncated)
        if mz.robot:
            j = observe(V, Q, E, born, S, F, par, st)
        else:
            if cache_geom != S[GEOM]:
                cell_cache[:, :] = -1
                cache_geom = S[GEOM]
            iy, ix = int(pos[1]), int(pos[0])
            if cell_cache[iy, ix] < 0:
                c, d2 = nearest_index(V, S[SIZE], x, inv_scale)
                cell_cache[iy, ix] = c
                dist_cache[iy, ix] = np.sqrt(d2)
            j = observe_at(V, Q, E, born, S, F, par, st, cell_cache[iy, ix], dist_cache[iy, ix])
        if j < 0:
            continue
        a_next = a if terminated else decide(rng, Q, born, P, j, scr)
        learn(V, Q, E, born, act, S, F, par, st, j, a_next)
        if st.done:
            end_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rec[episodes])
            episodes += 1
