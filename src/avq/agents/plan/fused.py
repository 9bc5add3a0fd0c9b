"""The model-based agents trained on a built-in maze inside one compiled loop: ``avq-plan``
(:func:`run_plan_maze`) and ``tabular-ps`` (:func:`run_ps_grid_maze`). The shared driver:
:mod:`avq.agents._maze_loop`."""

from __future__ import annotations

import numpy as np
from numba import njit

from avq._numba import borrowed
from avq.quantizer import nearest_index
from avq.agents._maze_loop import (DONE, NEED_CAPACITY, RECORDS_FULL, borrowed_maze, maze_move, maze_observation,
                                   maze_start)
from avq.agents._td import epsilon_greedy
from avq.agents.plan import kernels as plan_core
from avq.agents.plan import model as _model

__all__ = ["run_plan_maze", "run_ps_grid_maze"]


@njit(cache=True, inline="always")
def _borrowed_model(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos,
                    prio, C, MP):
    """The model's arrays (:class:`avq.agents.plan.model.ModelArrays`) as borrowed views, for a fused loop."""
    return (borrowed(cnt), borrowed(rsum), borrowed(head), borrowed(Q), borrowed(Vm), borrowed(e_to), borrowed(e_next),
            borrowed(e_n), borrowed(e_disc), borrowed(e_r), borrowed(p_head), borrowed(p_sa), borrowed(p_edge),
            borrowed(p_next), borrowed(heap), borrowed(hpos), borrowed(prio), borrowed(C), borrowed(MP))


@njit(cache=True)
def run_plan_maze(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to, e_next, e_n,
                  e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, rng, env_rng, mz, pos, budget_steps,
                  budget_episodes, rec):
    """Train ``avq-plan`` on a maze: :func:`avq.agents.plan.kernels.start` and ``step`` at every step, as
    ``PlanningAVQ`` does stepping the environment. On GridMaze the nearest cell of every square is kept
    while the codebook does not change. Returns ``(steps, episodes, status)``; ``NEED_CAPACITY`` when the
    arrays may not hold what the next step adds."""
    (V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs) = (
        borrowed(V), borrowed(inv_scale), borrowed(P), borrowed(IP), borrowed(S), borrowed(F), borrowed(xs),
        borrowed(mem_x), borrowed(mem_i), borrowed(mem_f), borrowed(e_xs))
    (cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C,
     MP) = _borrowed_model(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                           hpos, prio, C, MP)
    mz, pos, rec = borrowed_maze(mz), borrowed(pos), borrowed(rec)
    steps = 0
    episodes = 0
    x = np.empty(V.shape[1])
    sonar = np.empty(mz.dirs.shape[0])
    cache_shape = (1, 1) if mz.robot else mz.walls.shape
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
            maze_start(env_rng, pos, mz)
            maze_observation(x, pos, mz, sonar)
            plan_core.start(V, inv_scale, P, IP, S, F, xs, mem_x, mem_i, mem_f, e_xs, cnt, rsum, head, Q, Vm, e_to,
                            e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C, MP, rng, x)
            continue
        if steps >= budget_steps:
            return steps, episodes, DONE
        r, terminated, collision = maze_move(env_rng, pos, S[plan_core.ACTION], mz)
        truncated = pos[2] >= mz.max_episode_steps
        maze_observation(x, pos, mz, sonar)
        steps += 1
        if mz.robot:
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
                     prio, C, MP, row_of, keys, T, TF, gamma, epsilon, n_backups, rng, env_rng, mz, pos, budget_steps,
                     budget_episodes, rec):
    """Prioritized sweeping (``tabular-ps``) on a GridMaze: a state for every position on its first visit and
    :func:`avq.agents.plan.model.ps_step` at every step, as ``PrioritizedSweeping`` does stepping the
    environment. ``T``: current row, current action, episode steps, rows added this episode, in-episode
    flag; ``TF[0]``: episode return. Returns ``(steps, episodes, status)``; ``NEED_CAPACITY`` when the
    model may not hold a new state and a new edge."""
    (cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap, hpos, prio, C,
     MP) = _borrowed_model(cnt, rsum, head, Q, Vm, e_to, e_next, e_n, e_disc, e_r, p_head, p_sa, p_edge, p_next, heap,
                           hpos, prio, C, MP)
    row_of, keys, T, TF = borrowed(row_of), borrowed(keys), borrowed(T), borrowed(TF)
    mz, pos, rec = borrowed_maze(mz), borrowed(pos), borrowed(rec)
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
            maze_start(env_rng, pos, mz)
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
        r, terminated, _ = maze_move(env_rng, pos, T[1], mz)
        truncated = pos[2] >= mz.max_episode_steps
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
