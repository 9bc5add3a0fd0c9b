"""The paper's codebook rules as named functions (SPEC §3 and §4).

Each function decides (or, for the merged profile, computes); the agent's kernels
(:mod:`avq.agents.avq_sarsa.kernels`) call them and apply the decisions to the codebook and the
values. Read them against SPEC.md line by line.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "CHI", "APPEND", "KEEP", "collision_rule", "may_append", "mean_square_difference", "similar_profiles",
    "merge_profiles",
]

#: Outcomes of :func:`collision_rule`.
CHI, APPEND, KEEP = 0, 1, 2


@njit(cache=True, inline="always")
def may_append(dist_to_nearest: float, d_min: float) -> bool:
    """SPEC §3: a new vector is never appended within ``d_min`` of an existing one."""
    return dist_to_nearest > d_min


@njit(cache=True, inline="always")
def collision_rule(dist_to_own: float, dist_to_nearest: float, d_min: float) -> str:
    """SPEC §3, on a collision at ``x`` while in cell ``i``.

    Args:
        dist_to_own: ``||y_i - x||`` (scaled), the current cell's vector to ``x``.
        dist_to_nearest: distance from ``x`` to its nearest vector (``<= dist_to_own``).
        d_min: minimum resolution.

    Returns:
        ``CHI`` when ``||y_i - x|| <= d_min``: set ``Q[i, a] = chi``.
        ``APPEND`` otherwise, if ``x`` is farther than ``d_min`` from every vector:
        append ``x`` as cell ``c``, ``Q[c] = Q[i]``, then ``Q[c, a] = chi``.
        ``KEEP`` when another vector lies within ``d_min`` of ``x``: no append and
        no assignment (only possible when ``x`` has left cell ``i``).
    """
    if dist_to_own <= d_min:
        return CHI
    if may_append(dist_to_nearest, d_min):
        return APPEND
    return KEEP


@njit(cache=True)
def mean_square_difference(q_i: np.ndarray, q_j: np.ndarray) -> float:
    """SPEC §4, criterion 2: ``(1/m) * sum_a (q_i[a] - q_j[a])**2``."""
    m = q_i.shape[0]
    total = 0.0
    for a in range(m):
        d = q_i[a] - q_j[a]
        total += d * d
    return total / m


@njit(cache=True, inline="always")
def similar_profiles(q_i: np.ndarray, q_j: np.ndarray, rho: float) -> bool:
    """SPEC §4, criterion 2: two profiles are similar when their mean square difference is below ``rho``."""
    return mean_square_difference(q_i, q_j) < rho


@njit(cache=True, inline="always")
def merge_profiles(q_i: np.ndarray, q_j: np.ndarray, out: np.ndarray) -> None:
    """SPEC §4: the merged cell's profile ``(Q[i] + Q[j]) / 2`` into ``out`` (which may be ``q_i``)."""
    for a in range(q_i.shape[0]):
        out[a] = (q_i[a] + q_j[a]) / 2.0
