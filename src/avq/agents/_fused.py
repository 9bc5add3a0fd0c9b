"""Fused training loops: a built-in maze's dynamics and the AVQ kernels in one compiled loop.

The loops call exactly the kernels of :mod:`avq.agents._avq_core` that the generic
path calls, draw from the same generators in the same order (the agent's for its
decisions, the environment's ``np_random`` for start positions) and apply the same
time limit, so that with the same seed both paths give identical codebooks,
values and episode records.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from avq._kernels import borrowed, nearest_index
from avq.agents._avq_core import (
    ACTION, BONUS, DONE, EPS, GEOM, IN_EPISODE, NEED_CAPACITY, RECORDS_FULL, SIZE,
    begin_episode, bonus_values, end_episode, greedy_ties, learn, nth_tie, observe, observe_at,
)
from avq.envs.grid_maze import grid_move
from avq.envs.robot_maze import random_start, robot_move, sonar_ranges


@njit(cache=True, inline="always")
def _borrow_state(V, Q, E, born, act, pc, inv_scale, P, IP, S, F):
    """Borrowed views (see :func:`avq._kernels.borrowed`) of the agent's state arrays."""
    return (borrowed(V), borrowed(Q), borrowed(E), borrowed(born), borrowed(act), borrowed(pc),
            borrowed(inv_scale), borrowed(P), borrowed(IP), borrowed(S), borrowed(F))


@njit(cache=True)
def run_grid_maze(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rng, env_rng,
                  walls, gx, gy, starts, fixed, max_episode_steps, pos, budget_steps, budget_episodes, rec):
    """Train on a GridMaze for at most ``budget_steps`` steps and ``budget_episodes`` episodes.

    ``pos`` holds the robot's ``x, y`` and the steps taken in the current episode;
    ``fixed`` is the fixed start ``(x, y)``, or ``(-1, -1)`` for random starts drawn
    like ``GridMaze.reset``. Returns ``(steps, episodes, status)``.
    """
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F = _borrow_state(V, Q, E, born, act, pc, inv_scale, P, IP, S, F)
    walls, starts, pos, rec = borrowed(walls), borrowed(starts), borrowed(pos), borrowed(rec)
    cap = V.shape[0]
    scr = np.empty((1, Q.shape[1]))  # bonus values of one cell (count-based exploration)
    steps = 0
    episodes = 0
    # Nearest cell of every grid position, valid while the codebook does not change.
    cell_cache = np.full(walls.shape, -1, dtype=np.int64)
    dist_cache = np.zeros(walls.shape)
    cache_geom = -1
    x = np.empty(2)
    x[0] = pos[0]
    x[1] = pos[1]
    while True:
        if S[IN_EPISODE] == 0:
            if steps >= budget_steps or episodes >= budget_episodes:
                return steps, episodes, DONE
            if episodes >= rec.shape[0]:
                return steps, episodes, RECORDS_FULL
            if S[SIZE] + 1 > cap:
                return steps, episodes, NEED_CAPACITY
            if fixed[0] >= 0:
                pos[0] = fixed[0]
                pos[1] = fixed[1]
            else:
                k = env_rng.integers(0, starts.shape[0])
                pos[0] = starts[k, 0]
                pos[1] = starts[k, 1]
            pos[2] = 0
            x[0] = pos[0]
            x[1] = pos[1]
            cell = begin_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x)
            if rng.random() < P[EPS]:
                S[ACTION] = rng.integers(0, Q.shape[1])
            elif P[BONUS] > 0.0:  # count-based exploration: the greedy decision on bonus values
                bonus_values(Q, born, P, cell, scr)
                b, n_ties = greedy_ties(scr, 0)
                S[ACTION] = b if n_ties == 1 else nth_tie(scr, 0, rng.integers(0, n_ties))
            else:
                b, n_ties = greedy_ties(Q, cell)
                S[ACTION] = b if n_ties == 1 else nth_tie(Q, cell, rng.integers(0, n_ties))
        if steps >= budget_steps:
            return steps, episodes, DONE
        if S[SIZE] + 3 > cap:
            return steps, episodes, NEED_CAPACITY
        a = S[ACTION]
        nx, ny, r, terminated, collision = grid_move(walls, pos[0], pos[1], a, gx, gy)
        pos[0] = nx
        pos[1] = ny
        pos[2] += 1
        truncated = pos[2] >= max_episode_steps
        x[0] = nx
        x[1] = ny
        steps += 1
        done = terminated or truncated
        if cache_geom != S[GEOM]:
            cell_cache[:, :] = -1
            cache_geom = S[GEOM]
        if cell_cache[ny, nx] < 0:
            c, d2 = nearest_index(V, S[SIZE], x, inv_scale)
            cell_cache[ny, nx] = c
            dist_cache[ny, nx] = np.sqrt(d2)
        j = observe_at(V, Q, E, born, S, F, P, IP, inv_scale, x, r, collision, done,
                       cell_cache[ny, nx], dist_cache[ny, nx])
        if j < 0:
            continue
        a_next = a
        if not terminated:
            if rng.random() < P[EPS]:
                a_next = rng.integers(0, Q.shape[1])
            elif P[BONUS] > 0.0:
                bonus_values(Q, born, P, j, scr)
                a_next, n_ties = greedy_ties(scr, 0)
                if n_ties > 1:
                    a_next = nth_tie(scr, 0, rng.integers(0, n_ties))
            else:
                a_next, n_ties = greedy_ties(Q, j)
                if n_ties > 1:
                    a_next = nth_tie(Q, j, rng.integers(0, n_ties))
        learn(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, j, a_next, terminated, done)
        if done:
            end_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rec[episodes])
            episodes += 1


@njit(cache=True)
def run_robot_maze(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rng, env_rng,
                   grid, gx, gy, starts, fixed, move, radius, dirs, sonar_range, observe_sonar,
                   max_episode_steps, pos, budget_steps, budget_episodes, rec):
    """Train on a RobotMaze (noise-free sonar) like :func:`run_grid_maze`.

    ``pos`` holds the robot's ``x, y`` and the steps of the current episode (as a float).
    Observations are rounded to float32 as the environment's are.
    """
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F = _borrow_state(V, Q, E, born, act, pc, inv_scale, P, IP, S, F)
    grid, starts, dirs, pos, rec = borrowed(grid), borrowed(starts), borrowed(dirs), borrowed(pos), borrowed(rec)
    cap = V.shape[0]
    scr = np.empty((1, Q.shape[1]))  # bonus values of one cell (count-based exploration)
    steps = 0
    episodes = 0
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
            if fixed[0] == fixed[0]:  # not NaN: fixed start
                pos[0] = fixed[0]
                pos[1] = fixed[1]
            else:
                pos[0], pos[1] = random_start(env_rng, starts, grid, radius, gx, gy)
            pos[2] = 0.0
            _robot_obs(x, pos, grid, radius, dirs, sonar_range, observe_sonar, sonar)
            cell = begin_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x)
            if rng.random() < P[EPS]:
                S[ACTION] = rng.integers(0, Q.shape[1])
            elif P[BONUS] > 0.0:  # count-based exploration: the greedy decision on bonus values
                bonus_values(Q, born, P, cell, scr)
                b, n_ties = greedy_ties(scr, 0)
                S[ACTION] = b if n_ties == 1 else nth_tie(scr, 0, rng.integers(0, n_ties))
            else:
                b, n_ties = greedy_ties(Q, cell)
                S[ACTION] = b if n_ties == 1 else nth_tie(Q, cell, rng.integers(0, n_ties))
        if steps >= budget_steps:
            return steps, episodes, DONE
        if S[SIZE] + 3 > cap:
            return steps, episodes, NEED_CAPACITY
        a = S[ACTION]
        pos[2] += 1.0
        pos[0], pos[1], r, terminated, collision = robot_move(grid, pos[0], pos[1], a, move, radius, gx, gy)
        truncated = pos[2] >= max_episode_steps
        _robot_obs(x, pos, grid, radius, dirs, sonar_range, observe_sonar, sonar)
        steps += 1
        done = terminated or truncated
        j = observe(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, r, collision, done)
        if j < 0:
            continue
        a_next = a
        if not terminated:
            if rng.random() < P[EPS]:
                a_next = rng.integers(0, Q.shape[1])
            elif P[BONUS] > 0.0:
                bonus_values(Q, born, P, j, scr)
                a_next, n_ties = greedy_ties(scr, 0)
                if n_ties > 1:
                    a_next = nth_tie(scr, 0, rng.integers(0, n_ties))
            else:
                a_next, n_ties = greedy_ties(Q, j)
                if n_ties > 1:
                    a_next = nth_tie(Q, j, rng.integers(0, n_ties))
        learn(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, j, a_next, terminated, done)
        if done:
            end_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rec[episodes])
            episodes += 1


@njit(cache=True, inline="always")
def _robot_obs(x, pos, grid, radius, dirs, sonar_range, observe_sonar, sonar):
    """The RobotMaze observation as the agent sees it: float32 values, as float64."""
    x[0] = np.float64(np.float32(pos[0]))
    x[1] = np.float64(np.float32(pos[1]))
    if observe_sonar:
        sonar_ranges(grid, pos[0], pos[1], radius, dirs, sonar_range, sonar)
        for k in range(sonar.shape[0]):
            x[2 + k] = np.float64(np.float32(sonar[k]))


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
def run_tabular_grid_maze(q, e, row_of, keys, T, TF, alpha, gamma, lam, epsilon, replacing, rng, env_rng,
                          walls, gx, gy, starts, fixed, max_episode_steps, pos, budget_steps, budget_episodes, rec):
    """Tabular Sarsa(λ) on a GridMaze, the same computation as ``TabularSarsa`` stepping the env.

    ``T``: rows in use, current row, current action, episode steps, rows added this
    episode, in-episode flag; ``TF[0]``: episode return. ``q`` and ``e`` must have a
    row for every position. Returns ``(steps, episodes)``.
    """
    q, e, row_of, keys, T, TF = borrowed(q), borrowed(e), borrowed(row_of), borrowed(keys), borrowed(T), borrowed(TF)
    walls, starts, pos, rec = borrowed(walls), borrowed(starts), borrowed(pos), borrowed(rec)
    steps = 0
    episodes = 0
    decay = gamma * lam
    m = q.shape[1]
    # The rows whose traces are non-zero, so that an update touches only those (the others would
    # change by 0 * step); rebuilt here because a call may start inside an episode.
    active = np.empty(q.shape[0], dtype=np.int64)
    is_active = np.zeros(q.shape[0], dtype=np.bool_)
    n_active = 0
    for r in range(T[0]):
        for b in range(m):
            if e[r, b] != 0.0:
                active[n_active] = r
                is_active[r] = True
                n_active += 1
                break
    while True:
        if T[5] == 0:
            if steps >= budget_steps or episodes >= budget_episodes or episodes >= rec.shape[0]:
                return steps, episodes
            if fixed[0] >= 0:
                pos[0] = fixed[0]
                pos[1] = fixed[1]
            else:
                k = env_rng.integers(0, starts.shape[0])
                pos[0] = starts[k, 0]
                pos[1] = starts[k, 1]
            pos[2] = 0
            for k in range(n_active):
                r = active[k]
                is_active[r] = False
                for b in range(m):
                    e[r, b] = 0.0
            n_active = 0
            T[3] = 0
            T[4] = 0
            TF[0] = 0.0
            s = _table_row(row_of, keys, T, pos[0], pos[1])
            T[1] = s
            if rng.random() < epsilon:
                T[2] = rng.integers(0, m)
            else:
                b, n_ties = greedy_ties(q, s)
                T[2] = b if n_ties == 1 else nth_tie(q, s, rng.integers(0, n_ties))
            T[5] = 1
        if steps >= budget_steps:
            return steps, episodes
        s = T[1]
        a = T[2]
        nx, ny, rew, terminated, _ = grid_move(walls, pos[0], pos[1], a, gx, gy)
        pos[0] = nx
        pos[1] = ny
        pos[2] += 1
        truncated = pos[2] >= max_episode_steps
        steps += 1
        T[3] += 1
        TF[0] += rew
        s2 = _table_row(row_of, keys, T, nx, ny)
        if terminated:
            a2 = a
            delta = rew - q[s, a]
        else:
            if rng.random() < epsilon:
                a2 = rng.integers(0, m)
            else:
                a2, n_ties = greedy_ties(q, s2)
                if n_ties > 1:
                    a2 = nth_tie(q, s2, rng.integers(0, n_ties))
            delta = rew + gamma * q[s2, a2] - q[s, a]
        if replacing:
            e[s, a] = 1.0
        else:
            e[s, a] += 1.0
        if not is_active[s]:
            is_active[s] = True
            active[n_active] = s
            n_active += 1
        step = alpha * delta
        for k in range(n_active):
            r = active[k]
            for b in range(m):
                q[r, b] += step * e[r, b]
                e[r, b] *= decay
        T[1] = s2
        T[2] = a2
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
