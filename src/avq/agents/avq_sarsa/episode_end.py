"""The end of an AVQ Sarsa(λ) episode: the merge pass (the paper's merging, docs/explanation/paper.md#merging),
pruning beyond the paper, the decay of the step size and of exploration, and the episode's record row."""

from __future__ import annotations

import numpy as np
from numba import njit

from avq._numba import row
from avq.agents._maze_loop import R_APPENDS, R_CELLS, R_DECISIONS, R_MERGES, R_REFUSED, R_RETURN, R_STEPS
from avq.agents.avq_sarsa.kernels import (
    APPENDS,
    DECISIONS,
    EP_RETURN,
    EP_STEPS,
    EPISODES,
    GEOM,
    IN_EPISODE,
    REFUSED,
    SIZE,
    FloatParam,
    IntParam,
)
from avq.quantizer import compact_rows, merge_kernel, mutual_nearest_pairs_kernel, nearest_pairs_kernel
from avq.rules import (
    mean_square_difference,
    merge_profiles,
    old_enough,
    same_greedy_action,
    similar_profiles,
    stale_cell,
)

__all__ = ["merge_pass", "prune_pass", "epsilon_at", "alpha_at", "end_episode"]


@njit(cache=True, inline="always")
def _shrunk(Q, E, act, S, size: int, new_size: int) -> None:
    """After cells were removed (merged or pruned): clear the freed rows and every trace, and count
    the new geometry."""
    Q[new_size:size, :] = 0.0
    E[:size, :] = 0.0
    act[0] = 0
    S[SIZE] = new_size
    S[GEOM] += 1


@njit(cache=True, inline="always")
def _mergeable(Q, born, P, IP, S, i: int, j: int) -> bool:
    """Whether the pair of cells ``(i, j)`` merges: the paper's criterion 2 (docs/explanation/paper.md#merging)
    and the guards beyond the paper (``merge_age``, ``merge_same_action``)."""
    if not similar_profiles(row(Q, i), row(Q, j), P[FloatParam.RHO]):
        return False
    if not old_enough(S[EPISODES], born[i, 0], born[j, 0], IP[IntParam.MERGE_AGE]):
        return False
    return not (IP[IntParam.MERGE_SAME_ACTION] and not same_greedy_action(row(Q, i), row(Q, j)))


@njit(cache=True)
def merge_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S) -> int:
    """The paper (docs/explanation/paper.md#merging): merge every mutually nearest pair whose profiles differ by less than rho.

    With ``merge_age > 0`` both cells must have lived ``merge_age`` complete episodes
    after the one that created them. Merged cells take the lower index; later cells
    move down. Returns the number of merges.
    """
    size = S[SIZE]
    if pc[0, 0] != S[GEOM]:  # the geometry changed since the pairs were found
        if IP[IntParam.MERGE_PAIRS] == 2:  # "nearest"
            found = nearest_pairs_kernel(V, size, inv_scale)
        else:  # "mutual" (0, the paper) or "mutual_ties" (1)
            found = mutual_nearest_pairs_kernel(V, size, inv_scale, IP[IntParam.MERGE_PAIRS] == 0)
        pc[0, 0] = S[GEOM]
        pc[0, 1] = found.shape[0]
        pc[1 : 1 + found.shape[0], :] = found
    pairs = pc[1 : 1 + pc[0, 1]]
    make_room = IP[IntParam.MAKE_ROOM] and S[REFUSED] > 0
    n_keep = 0
    for k in range(pairs.shape[0]):
        n_keep += _mergeable(Q, born, P, IP, S, pairs[k, 0], pairs[k, 1])
    if n_keep == 0 and not make_room:
        return 0  # (most passes: no allocation)
    keep = np.zeros(pairs.shape[0], dtype=np.bool_)
    for k in range(pairs.shape[0]):
        keep[k] = _mergeable(Q, born, P, IP, S, pairs[k, 0], pairs[k, 1])  # (the same answers again)
    if make_room:
        # Beyond the paper: the budget refused growth this episode; make room by merging as many more
        # pairs, those with the same greedy action and the most similar profiles first.
        extra = min(S[REFUSED], pairs.shape[0] - n_keep)
        for _ in range(extra):
            best = -1
            best_d = np.inf
            for k in range(pairs.shape[0]):
                i, j = pairs[k, 0], pairs[k, 1]
                if keep[k] or not same_greedy_action(row(Q, i), row(Q, j)):
                    continue
                d = mean_square_difference(row(Q, i), row(Q, j))
                if d < best_d:
                    best, best_d = k, d
            if best < 0:
                break
            keep[best] = True
            n_keep += 1
    if n_keep == 0:
        return 0
    chosen = np.empty((n_keep, 2), dtype=np.int64)
    c = 0
    for k in range(pairs.shape[0]):
        if keep[k]:
            i, j = pairs[k, 0], pairs[k, 1]
            chosen[c, 0] = i
            chosen[c, 1] = j
            c += 1
            merge_profiles(row(Q, i), row(Q, j), row(Q, i))  # docs/explanation/paper.md#merging
            born[i, 0] = S[EPISODES]
            born[i, 1] = max(born[i, 1], born[j, 1])
            for b in range(2, born.shape[1]):
                born[i, b] += born[j, b]
    mapping = merge_kernel(V, size, chosen)
    compact_rows(Q, mapping)
    compact_rows(born, mapping)
    _shrunk(Q, E, act, S, size, size - n_keep)
    return n_keep


@njit(cache=True)
def prune_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S) -> int:
    """Beyond the paper: remove every cell older than ``prune_after`` episodes in which the agent has
    taken no decision for the last ``prune_after`` episodes (the oldest such cell stays if none
    else would). Later cells move down. Returns the number removed."""
    size = S[SIZE]
    k = IP[IntParam.PRUNE_AFTER]
    now = S[EPISODES]
    stale = np.zeros(size, dtype=np.bool_)
    n_stale = 0
    for r in range(size):
        if stale_cell(now, born[r, 0], born[r, 1], k):
            stale[r] = True
            n_stale += 1
    if n_stale == size:
        stale[0] = False
        n_stale -= 1
    if n_stale == 0:
        return 0
    w = 0
    for r in range(size):
        if stale[r]:
            continue
        if w != r:
            for d in range(V.shape[1]):
                V[w, d] = V[r, d]
            for b in range(Q.shape[1]):
                Q[w, b] = Q[r, b]
            for b in range(born.shape[1]):
                born[w, b] = born[r, b]
        w += 1
    _shrunk(Q, E, act, S, size, w)
    return n_stale


@njit(cache=True, inline="always")
def _decayed(start: float, decay: float, floor: float, episodes: int) -> float:
    """``max(floor, start * decay ** episodes)``; exactly ``start`` when ``decay`` is 1."""
    if decay == 1.0:
        return start
    return max(floor, start * decay**episodes)


@njit(cache=True)
def epsilon_at(P, episodes: int) -> float:
    """The exploration rate after ``episodes`` episodes: ``max(epsilon_min, epsilon * decay ** episodes)``."""
    return _decayed(P[FloatParam.EPSILON], P[FloatParam.EPSILON_DECAY], P[FloatParam.EPSILON_MIN], episodes)


@njit(cache=True)
def alpha_at(P, episodes: int) -> float:
    """The step size after ``episodes`` episodes: ``max(alpha_min, alpha * decay ** episodes)``."""
    return _decayed(P[FloatParam.ALPHA], P[FloatParam.ALPHA_DECAY], P[FloatParam.ALPHA_MIN], episodes)


@njit(cache=True)
def end_episode(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, rec_row) -> None:
    """Count the episode, run the merge pass when due, and fill its record row."""
    S[EPISODES] += 1
    S[IN_EPISODE] = 0
    P[FloatParam.EPSILON_NOW] = epsilon_at(P, S[EPISODES])
    P[FloatParam.ALPHA_NOW] = alpha_at(P, S[EPISODES])
    merges = 0
    if IP[IntParam.MERGE_EVERY] > 0 and S[EPISODES] % IP[IntParam.MERGE_EVERY] == 0:
        merges = merge_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S)
    if IP[IntParam.PRUNE_AFTER] > 0:
        prune_pass(V, Q, E, born, act, pc, inv_scale, P, IP, S)
    rec_row[R_STEPS] = S[EP_STEPS]
    rec_row[R_RETURN] = F[EP_RETURN]
    rec_row[R_CELLS] = S[SIZE]
    rec_row[R_APPENDS] = S[APPENDS]
    rec_row[R_MERGES] = merges
    rec_row[R_REFUSED] = S[REFUSED]
    rec_row[R_DECISIONS] = S[DECISIONS]
