"""AVQ Sarsa(λ) trained on a built-in maze inside one compiled loop (the shared driver:
:mod:`avq.agents._maze_loop`).

The loop counts no references (:func:`avq._numba.borrowed`): it borrows the agent's arrays and
generator, the environment's generator, the maze, and its own arrays (:class:`Work`, made by
:func:`run_avq_maze`, which holds them while the loop runs), so that handing them to the inlined
kernels at every step costs nothing.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from avq._numba import Compiled, NoAliasPipeline, borrowed, borrowed_record
from avq.agents._maze_loop import (
    DONE,
    GO_ON,
    NEED_CAPACITY,
    NearestCache,
    borrowed_maze,
    budget_left,
    cached_nearest,
    maze_move,
    maze_observation,
    maze_start,
    maze_types,
    nearest_cache,
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
    begin_episode_in,
    decide,
    first_vector,
    learn,
    observe,
    observe_at,
)
from avq.quantizer import nearest_index

__all__ = ["run_avq_maze", "fused_loop", "Work"]


class Work(NamedTuple):
    """The loop's own arrays, made once per call: the observation, the bonus values of one cell (count-based
    exploration), the sonar ranges, and on GridMaze the nearest cell of every square."""

    x: np.ndarray
    scr: np.ndarray
    sonar: np.ndarray
    near: NearestCache


@njit(cache=True)
def run_avq_maze(cells: Cells, rng, env_rng, mz, pos, budget_steps, budget_episodes, rec):
    """Train AVQ Sarsa(λ) on a maze for at most ``budget_steps`` steps and ``budget_episodes`` episodes.

    ``cells`` holds the agent's arrays, ``mz`` the maze (:class:`~avq.agents._maze_loop.Maze`); ``pos`` holds the robot's ``x, y`` and
    the steps taken in the current episode. On GridMaze, the nearest cell of every square is kept
    while the codebook does not change. Returns ``(steps, episodes, status)``.
    """
    work = Work(
        np.empty(cells.V.shape[1]), np.empty((1, cells.Q.shape[1])), np.empty(mz.dirs.shape[0]), nearest_cache(mz)
    )
    return _train(cells, work, rng, env_rng, mz, pos, budget_steps, budget_episodes, rec)  # (holds work meanwhile)


#: :func:`run_avq_maze` called directly (:class:`~avq._numba.Compiled`), one for each maze's types: every agent
#: hands it arrays of the same types, and typing its records through Numba's dispatcher costs a quarter of a
#: millisecond at every learn(), as much as a thousand steps.
_LOOPS: dict[tuple, Compiled] = {}


def fused_loop(mz) -> Compiled:
    """:func:`run_avq_maze`, called directly after its first call, for a maze of the types of ``mz``."""
    return _LOOPS.setdefault(maze_types(mz), Compiled(run_avq_maze))


@njit(cache=True, pipeline_class=NoAliasPipeline)
def _train(cells: Cells, work: Work, rng, env_rng, mz, pos, budget_steps, budget_episodes, rec):
    """:func:`run_avq_maze`'s loop, on borrowed views of everything it is given. Compiled with the arguments'
    arrays declared not to overlap (:class:`~avq._numba.NoAliasPipeline`): the agent's arrays are disjoint views
    of its buffers, and the other arrays are arrays of their own."""
    # (Taken out of the records once: the kernels take the arrays they write one by one. Under Numba 0.68 an
    # inlined kernel that writes through a record argument can lose those writes in this loop.)
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F = borrowed_record(cells)
    x, scr, sonar = borrowed(work.x), borrowed(work.scr), borrowed(work.sonar)
    near, near_d2, near_seen = borrowed_record(work.near)
    rng, env_rng = borrowed(rng), borrowed(env_rng)
    mz, pos, rec = borrowed_maze(mz), borrowed(pos), borrowed(rec)
    par = Params(P, IP, inv_scale)  # (read only: the kernels write the arrays they take one by one)
    cap = V.shape[0]
    steps = 0
    episodes = 0
    while True:
        if S[IN_EPISODE] == 0:
            status = budget_left(steps, episodes, budget_steps, budget_episodes, rec)
            if status != GO_ON:
                return steps, episodes, status
            if S[SIZE] + 1 > cap:
                return steps, episodes, NEED_CAPACITY
            maze_start(env_rng, pos, mz)
            maze_observation(x, pos, mz, sonar)
            first_vector(V, Q, E, born, S, P, x)
            if mz.robot:
                cell, _ = nearest_index(V, S[SIZE], x, inv_scale)
            else:
                cell, _ = cached_nearest(near, near_d2, near_seen, V, S[SIZE], S[GEOM], x, inv_scale, pos)
            begin_episode_in(E, born, act, S, F, cell)
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
            c, d2 = cached_nearest(near, near_d2, near_seen, V, S[SIZE], S[GEOM], x, inv_scale, pos)
            j = observe_at(V, Q, E, born, S, F, par, st, c, d2)
        if j < 0:
            continue
        a_next = a if terminated else decide(rng, Q, born, P, j, scr)
        learn(V, Q, E, born, act, S, F, par, st, j, a_next)
        if st.done:
            end_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, borrowed(rec[episodes]))
            episodes += 1
