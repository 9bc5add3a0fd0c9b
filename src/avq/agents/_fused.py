"""Fused training: a built-in maze's dynamics and an agent's rules in one compiled loop.

:func:`plan` decides whether an environment can be fused: a ``GridMaze``, or a ``RobotMaze``
with noise-free sonar, under Gymnasium's standard wrappers (:func:`avq.envs.compiled.compiled_maze`).
The loops read the maze only through its public, frozen description
(:class:`~avq.envs.grid_maze.GridDynamics`, :class:`~avq.envs.robot_maze.RobotDynamics`) and step
it with the maze's own compiled moves. They call the very kernels of the generic path
(:mod:`avq.agents._avq_core`, :mod:`avq.agents._td`), draw from the same generators in the same
order (the agent's for its decisions, the environment's ``np_random`` for start positions) and
apply the same step limit, so that with the same seed both paths give identical results.

A loop runs until a budget of steps or episodes is spent and returns ``(steps, episodes,
status)``; :func:`drive` calls it, grows the agent's arrays when asked, and hands the episode
back to the environment object (position and elapsed steps), so that stepping it from Python
goes on from there.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from numba import njit

from avq._kernels import borrowed, nearest_index
from avq.agents._avq_core import (
    ACTION, DONE, GEOM, IN_EPISODE, N_R, NEED_CAPACITY, RECORDS_FULL, SIZE,
    begin_episode, decide, end_episode, learn, observe, observe_at,
)
from avq.agents import _model
from avq.agents import _plan_core as plan_core
from avq.agents._td import clear_traces, epsilon_greedy, table_step
from avq.envs.compiled import CompiledMaze, compiled_maze
from avq.envs.grid_maze import GridDynamics, grid_move, slipped
from avq.envs.robot_maze import random_start, robot_move, sonar_ranges

__all__ = ["plan", "maze_arguments", "drive", "run_avq_maze", "run_tabular_grid_maze", "run_plan_maze",
           "run_ps_grid_maze"]


def plan(env, grid_only: bool = False) -> CompiledMaze | None:
    """The maze a fused loop can run for ``env``, or None (step the environment from Python).

    Fused: a ``GridMaze``, or (unless ``grid_only``) a ``RobotMaze`` with noise-free sonar, under
    Gymnasium's standard wrappers only; any other wrapper may change what a step does.
    """
    maze = compiled_maze(env)
    if maze is None:
        return None
    if isinstance(maze.dynamics, GridDynamics):
        return maze
    if grid_only or maze.dynamics.sonar_noise != 0.0:
        return None
    return maze


def maze_arguments(maze: CompiledMaze) -> tuple:
    """The maze's part of a fused loop's arguments: ``(robot, walls, gx, gy, starts, fixed, move,
    radius, slip, dirs, sonar_range, observe_sonar, max_episode_steps)``; ``fixed`` is the fixed start,
    or NaN for random starts."""
    d = maze.dynamics
    fixed = np.array(d.fixed_start if d.fixed_start is not None else (np.nan, np.nan), dtype=np.float64)
    if isinstance(d, GridDynamics):
        return (False, d.walls, float(d.goal[0]), float(d.goal[1]), d.starts, fixed, 1.0, 0.0, d.slip,
                np.zeros((0, 2)), 0.0, False, maze.max_episode_steps)
    return (True, d.grid, d.goal[0], d.goal[1], d.starts, fixed, d.move, d.radius, 0.0, d.sonar_directions,
            d.sonar_range, d.observe_sonar, maze.max_episode_steps)


def drive(maze: CompiledMaze, kernel: Callable, grow: Callable[[], None], max_steps: int, max_episodes: int,
          max_records: int) -> tuple[int, np.ndarray]:
    """Run ``kernel(pos, budget_steps, budget_episodes, rec)`` from the environment's current episode
    until a budget is spent; returns ``(steps, records)`` and leaves the environment where the loop
    stopped. ``grow()`` makes room when the kernel returns ``NEED_CAPACITY``."""
    pos = np.array(maze.episode_state(), dtype=np.float64)  # x, y, steps elapsed in the episode
    rec = np.zeros((min(max_episodes, max_records), N_R))
    steps = episodes = 0
    while True:
        n, eps, status = kernel(pos, max_steps - steps, len(rec) - episodes, rec[episodes:])
        steps += n
        episodes += eps
        if status != NEED_CAPACITY:
            break
        grow()
    maze.set_episode_state(pos[0], pos[1], int(pos[2]))
    return steps, rec[:episodes]


@njit(cache=True, inline="always")
def _start(env_rng, pos, robot, walls, gx, gy, starts, fixed, radius) -> None:
    """A new episode's start, drawn as the maze's ``reset`` draws it."""
    if fixed[0] == fixed[0]:  # not NaN: a fixed start
        pos[0] = fixed[0]
        pos[1] = fixed[1]
    elif robot:
        pos[0], pos[1] = random_start(env_rng, starts, walls, radius, gx, gy)
    else:
        k = env_rng.integers(0, starts.shape[0])
        pos[0] = starts[k, 0]
        pos[1] = starts[k, 1]
    pos[2] = 0.0


@njit(cache=True, inline="always")
def _move(env_rng, pos, a, robot, walls, gx, gy, move, radius, slip):
    """One step of the maze from ``pos`` (in place): ``(reward, terminated, collision)``. GridMaze's
    moves slip as its ``step`` makes them slip (from the maze's generator)."""
    if robot:
        pos[0], pos[1], r, terminated, collision = robot_move(walls, pos[0], pos[1], a, move, radius, gx, gy)
    else:
        a = slipped(env_rng, a, slip)
        nx, ny, r, terminated, collision = grid_move(walls, int(pos[0]), int(pos[1]), a, int(gx), int(gy))
        pos[0] = nx
        pos[1] = ny
    pos[2] += 1.0
    return r, terminated, collision


@njit(cache=True, inline="always")
def _observation(x, pos, robot, walls, radius, dirs, sonar_range, observe_sonar, sonar) -> None:
    """The observation at ``pos`` as the agent sees it: GridMaze's integer ``(x, y)``; RobotMaze's
    float32 values (and sonar ranges), as float64."""
    if not robot:
        x[0] = pos[0]
        x[1] = pos[1]
        return
    x[0] = np.float64(np.float32(pos[0]))
    x[1] = np.float64(np.float32(pos[1]))
    if observe_sonar:
        sonar_ranges(walls, pos[0], pos[1], radius, dirs, sonar_range, sonar)
        for k in range(sonar.shape[0]):
            x[2 + k] = np.float64(np.float32(sonar[k]))


@njit(cache=True)
def run_avq_maze(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rng, env_rng,
                 robot, walls, gx, gy, starts, fixed, move, radius, slip, dirs, sonar_range, observe_sonar,
                 max_episode_steps, pos, budget_steps, budget_episodes, rec):
    """Train AVQ Sarsa(λ) on a maze for at most ``budget_steps`` steps and ``budget_episodes`` episodes.

    The maze's arguments are those of :func:`maze_arguments`; ``pos`` holds the robot's ``x, y`` and
    the steps taken in the current episode. On GridMaze, the nearest cell of every square is kept
    while the codebook does not change. Returns ``(steps, episodes, status)``.
    """
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F = (
        borrowed(V), borrowed(Q), borrowed(E), borrowed(born), borrowed(act), borrowed(pc),
        borrowed(inv_scale), borrowed(P), borrowed(IP), borrowed(S), borrowed(F))
    walls, starts, dirs, pos, rec = borrowed(walls), borrowed(starts), borrowed(dirs), borrowed(pos), borrowed(rec)
    cap = V.shape[0]
    scr = np.empty((1, Q.shape[1]))  # bonus values of one cell (count-based exploration)
    steps = 0
    episodes = 0
    cache_shape = (1, 1) if robot else walls.shape
    cell_cache = np.full(cache_shape, -1, dtype=np.int64)
    dist_cache = np.zeros(cache_shape)
    cache_geom = -1
    x = np.empty(V.shape[1])
    sonar = np.empty(dirs.shape[0])
    while True:
        if S[IN_EPISODE] == 0:
            if steps >= budget_steps or episodes >= budget_episodes:
                return steps, episodes, DONE
            if episodes >= rec.shape[0]:
                return steps, episodes, RECORDS_FULL
            if S[SIZE] + 1 > cap:
                return steps, episodes, NEED_CAPACITY
            _start(env_rng, pos, robot, walls, gx, gy, starts, fixed, radius)
            _observation(x, pos, robot, walls, radius, dirs, sonar_range, observe_sonar, sonar)
            cell = begin_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x)
            S[ACTION] = decide(rng, Q, born, P, cell, scr)
        if steps >= budget_steps:
            return steps, episodes, DONE
        if S[SIZE] + 3 > cap:
            return steps, episodes, NEED_CAPACITY
        a = S[ACTION]
        r, terminated, collision = _move(env_rng, pos, a, robot, walls, gx, gy, move, radius, slip)
        truncated = pos[2] >= max_episode_steps
        _observation(x, pos, robot, walls, radius, dirs, sonar_range, observe_sonar, sonar)
        steps += 1
        done = terminated or truncated
        if robot:
            j = observe(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, r, collision, done)
        else:
            if cache_geom != S[GEOM]:
                cell_cache[:, :] = -1
                cache_geom = S[GEOM]
            iy, ix = int(pos[1]), int(pos[0])
            if cell_cache[iy, ix] < 0:
                c, d2 = nearest_index(V, S[SIZE], x, inv_scale)
                cell_cache[iy, ix] = c
                dist_cache[iy, ix] = np.sqrt(d2)
            j = observe_at(V, Q, E, born, S, F, P, IP, inv_scale, x, r, collision, done,
                           cell_cache[iy, ix], dist_cache[iy, ix])
        if j < 0:
            continue
        a_next = a if terminated else decide(rng, Q, born, P, j, scr)
        learn(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, j, a_next, terminated, done)
        if done:
            end_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rec[episodes])
            episodes += 1


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
def run_tabular_grid_maze(q, e, act, row_of, keys, T, TF, alpha, gamma, lam, epsilon, replacing, rng, env_rng,
                          robot, walls, gx, gy, starts, fixed, move, radius, slip, dirs, sonar_range,
                          observe_sonar, max_episode_steps, pos, budget_steps, budget_episodes, rec):
    """Tabular Sarsa(λ) on a GridMaze: :func:`avq.agents._td.table_step` at every step, as ``TabularSarsa``
    does stepping the environment.

    ``T``: rows in use, current row, current action, episode steps, rows added this
    episode, in-episode flag; ``TF[0]``: episode return. ``q`` and ``e`` must have a
    row for every position; ``act`` is the active list of :mod:`avq.agents._td`.
    Returns ``(steps, episodes, status)``. (GridMaze only: ``robot`` must be False.)
    """
    q, e, act, row_of, keys, T, TF = (borrowed(q), borrowed(e), borrowed(act), borrowed(row_of), borrowed(keys),
                                      borrowed(T), borrowed(TF))
    walls, starts, pos, rec = borrowed(walls), borrowed(starts), borrowed(pos), borrowed(rec)
    steps = 0
    episodes = 0
    while True:
        if T[5] == 0:
            if steps >= budget_steps or episodes >= budget_episodes:
                return steps, episodes, DONE
            if episodes >= rec.shape[0]:
                return steps, episodes, RECORDS_FULL
            _start(env_rng, pos, False, walls, gx, gy, starts, fixed, radius)
            clear_traces(e, act)
            T[3] = 0
            T[4] = 0
            TF[0] = 0.0
            T[1] = _table_row(row_of, keys, T, int(pos[0]), int(pos[1]))
            T[2] = epsilon_greedy(rng, q, T[1], epsilon)
            T[5] = 1
        if steps >= budget_steps:
            return steps, episodes, DONE
        r, terminated, _ = _move(env_rng, pos, T[2], False, walls, gx, gy, move, radius, slip)
        truncated = pos[2] >= max_episode_steps
        steps += 1
        T[3] += 1
        TF[0] += r
        s2 = _table_row(row_of, keys, T, int(pos[0]), int(pos[1]))
        T[2] = table_step(rng, q, e, act, T[1], T[2], r, s2, terminated, epsilon, alpha, gamma, lam, replacing)
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


@njit(cache=True, inline="always")
def _borrowed_model(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
                    prio, C, MP):
    """The model's arrays (:class:`avq.agents._model.ModelArrays`) as borrowed views, for a fused loop."""
    return (borrowed(cnt), borrowed(rsum), borrowed(head), borrowed(Q), borrowed(Vm), borrowed(e_to), borrowed(e_next),
            borrowed(e_n), borrowed(e_disc), borrowed(e_r), borrowed(p_head), borrowed(p_sa), borrowed(p_edge),
            borrowed(p_next), borrowed(heap), borrowed(hpos), borrowed(prio), borrowed(C), borrowed(MP))


@njit(cache=True)
def run_plan_maze(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n,
                  e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, rng, env_rng,
                  robot, walls, gx, gy, starts, fixed, move, radius, slip, dirs, sonar_range, observe_sonar,
                  max_episode_steps, pos, budget_steps, budget_episodes, rec):
    """Train ``avq-plan`` on a maze: :func:`avq.agents._plan_core.start` and ``step`` at every step, as
    ``PlanningAVQ`` does stepping the environment. On GridMaze the nearest cell of every square is kept
    while the codebook does not change. Returns ``(steps, episodes, status)``; ``NEED_CAPACITY`` when the
    arrays may not hold what the next step adds."""
    (V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs) = (
        borrowed(V), borrowed(inv_scale), borrowed(P), borrowed(IP), borrowed(S), borrowed(F), borrowed(xs),
        borrowed(mem_x), borrowed(mem_i), borrowed(mem_f), borrowed(e_xs))
    (cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C,
     MP) = _borrowed_model(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                           hpos, prio, C, MP)
    walls, starts, dirs, pos, rec = borrowed(walls), borrowed(starts), borrowed(dirs), borrowed(pos), borrowed(rec)
    steps = 0
    episodes = 0
    x = np.empty(V.shape[1])
    sonar = np.empty(dirs.shape[0])
    cache_shape = (1, 1) if robot else walls.shape
    cell_cache = np.full(cache_shape, -1, dtype=np.int64)
    dist_cache = np.zeros(cache_shape)
    cache_geom = -1
    while True:
        if not plan_core.room_left(V, S, C, e_to, cnt) or e_xs.shape[0] < e_to.shape[0]:
            return steps, episodes, NEED_CAPACITY
        if S[plan_core.IN_EPISODE] == 0:
            if steps >= budget_steps or episodes >= budget_episodes:
                return steps, episodes, DONE
            if episodes >= rec.shape[0]:
                return steps, episodes, RECORDS_FULL
            _start(env_rng, pos, robot, walls, gx, gy, starts, fixed, radius)
            _observation(x, pos, robot, walls, radius, dirs, sonar_range, observe_sonar, sonar)
            plan_core.start(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to,
                            e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, rng, x)
            continue
        if steps >= budget_steps:
            return steps, episodes, DONE
        r, terminated, collision = _move(env_rng, pos, S[plan_core.ACTION], robot, walls, gx, gy, move, radius, slip)
        truncated = pos[2] >= max_episode_steps
        _observation(x, pos, robot, walls, radius, dirs, sonar_range, observe_sonar, sonar)
        steps += 1
        if robot:
            j, d2 = nearest_index(V, S[plan_core.SIZE], x, inv_scale)
        else:
            if cache_geom != S[plan_core.GEOM]:
                cell_cache[:, :] = -1
                cache_geom = S[plan_core.GEOM]
            iy, ix = int(pos[1]), int(pos[0])
            if cell_cache[iy, ix] < 0:
                cell_cache[iy, ix], dist_cache[iy, ix] = nearest_index(V, S[plan_core.SIZE], x, inv_scale)
            j, d2 = cell_cache[iy, ix], dist_cache[iy, ix]
        if plan_core.goes_on(P, IP, S, F, r, j, d2, collision, terminated or truncated):
            continue
        a = plan_core.end_transition(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm,
                                     e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C,
                                     MP, rng, x, collision, terminated, truncated, j, d2)
        if a == plan_core.ENDED:
            plan_core.end_record(S, F, rec[episodes])
            episodes += 1


@njit(cache=True)
def run_ps_grid_maze(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
                     prio, C, MP, row_of, keys, T, TF, gamma, epsilon, n_backups, rng, env_rng,
                     robot, walls, gx, gy, starts, fixed, move, radius, slip, dirs, sonar_range, observe_sonar,
                     max_episode_steps, pos, budget_steps, budget_episodes, rec):
    """Prioritized sweeping (``tabular-ps``) on a GridMaze: a state for every position on its first visit and
    :func:`avq.agents._model.ps_step` at every step, as ``PrioritizedSweeping`` does stepping the
    environment. ``T``: current row, current action, episode steps, rows added this episode, in-episode
    flag; ``TF[0]``: episode return. Returns ``(steps, episodes, status)``; ``NEED_CAPACITY`` when the
    model may not hold a new state and a new edge."""
    (cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C,
     MP) = _borrowed_model(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                           hpos, prio, C, MP)
    row_of, keys, T, TF = borrowed(row_of), borrowed(keys), borrowed(T), borrowed(TF)
    walls, starts, pos, rec = borrowed(walls), borrowed(starts), borrowed(pos), borrowed(rec)
    steps = 0
    episodes = 0
    while True:
        if C[_model.N_STATES] + 1 > cnt.shape[0] or C[_model.N_EDGES] + 1 > e_to.shape[0]:
            return steps, episodes, NEED_CAPACITY
        if T[4] == 0:
            if steps >= budget_steps or episodes >= budget_episodes:
                return steps, episodes, DONE
            if episodes >= rec.shape[0]:
                return steps, episodes, RECORDS_FULL
            _start(env_rng, pos, False, walls, gx, gy, starts, fixed, radius)
            T[2] = 0
            T[3] = 0
            TF[0] = 0.0
            T[0] = _ps_row(row_of, keys, T, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa,
                           p_edge, p_next, heap, hpos, prio, C, MP, int(pos[0]), int(pos[1]))
            T[1] = epsilon_greedy(rng, Q, T[0], epsilon)
            T[4] = 1
            continue
        if steps >= budget_steps:
            return steps, episodes, DONE
        r, terminated, _ = _move(env_rng, pos, T[1], False, walls, gx, gy, move, radius, slip)
        truncated = pos[2] >= max_episode_steps
        steps += 1
        T[2] += 1
        TF[0] += r
        s2 = _ps_row(row_of, keys, T, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge,
                     p_next, heap, hpos, prio, C, MP, int(pos[0]), int(pos[1]))
        T[1] = _model.ps_step(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                          hpos, prio, C, MP, rng, T[0], T[1], r, gamma, s2, terminated, epsilon, n_backups)
        T[0] = s2
        if terminated or truncated:
            T[4] = 0
            rec[episodes, 0] = T[2]
            rec[episodes, 1] = TF[0]
            rec[episodes, 2] = C[_model.N_STATES]
            rec[episodes, 3] = T[3]
            rec[episodes, 4] = 0
            rec[episodes, 5] = 0
            rec[episodes, 6] = T[2]
            episodes += 1
            if C[_model.N_STATES] + 1 > cnt.shape[0] or C[_model.N_EDGES] + 1 > e_to.shape[0]:
                return steps, episodes, NEED_CAPACITY


@njit(cache=True, inline="always")
def _ps_row(row_of, keys, T, cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
            hpos, prio, C, MP, x, y):
    """The state of position (x, y), made (in order of first visit) when new."""
    r = row_of[y, x]
    if r < 0:
        r = _model.add_state(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next,
                             heap, hpos, prio, C, MP)
        row_of[y, x] = r
        keys[r, 0] = x
        keys[r, 1] = y
        T[3] += 1
    return r
