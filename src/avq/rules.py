"""Every rule that grows, splits or merges the partition, as a named pure function.

One place for each: the agents' kernels (:mod:`avq.agents.avq_sarsa.kernels`,
:mod:`avq.agents.plan.kernels`) call these and apply the decisions to the codebook, the values
and the model. The first group is the paper's, to be read line by line against
its sections Acting, Growing and Merging in docs/explanation/paper.md;
the second holds the rules beyond the paper, each named after the agent parameter that switches
it on. The functions take numbers (and value rows), never an agent's state arrays, so that each
can be tested with a situation written out by hand.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "CHI",
    "APPEND",
    "KEEP",
    "decision_goes_on",
    "collision_rule",
    "may_append",
    "mean_square_difference",
    "similar_profiles",
    "merge_profiles",
    "repeat_limit_reached",
    "reward_jump",
    "value_jump",
    "collision_split",
    "closes_cycle",
    "stayed_too_long",
    "outcome_disagrees",
    "split_matters",
    "old_enough",
    "same_greedy_action",
    "stale_cell",
    "merged_decision_leaves",
]

#: Outcomes of :func:`collision_rule`.
CHI, APPEND, KEEP = 0, 1, 2


@njit(cache=True, inline="always")
def decision_goes_on(same_cell: bool, collision: bool, done: bool) -> bool:
    """The paper (Acting, docs/explanation/paper.md#acting): a decision is repeated while the observation stays in its cell, without a collision, and
    the episode goes on; otherwise the aggregate transition ends."""
    return same_cell and not (collision or done)


@njit(cache=True, inline="always")
def may_append(dist_to_nearest: float, d_min: float) -> bool:
    """The paper (Growing, docs/explanation/paper.md#growing): a new vector is never appended within ``d_min`` of an existing one."""
    return dist_to_nearest > d_min


@njit(cache=True, inline="always")
def collision_rule(dist_to_own: float, dist_to_nearest: float, d_min: float) -> int:
    """The paper (Growing, docs/explanation/paper.md#growing), on a collision at ``x`` while in cell ``i``.

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
    """The paper (Merging, criterion 2, docs/explanation/paper.md#merging): ``(1/m) * sum_a (q_i[a] - q_j[a])**2``."""
    m = q_i.shape[0]
    total = 0.0
    for a in range(m):
        d = q_i[a] - q_j[a]
        total += d * d
    return total / m


@njit(cache=True, inline="always")
def similar_profiles(q_i: np.ndarray, q_j: np.ndarray, rho: float) -> bool:
    """The paper (Merging, criterion 2, docs/explanation/paper.md#merging): two profiles are similar when their mean square difference is below ``rho``."""
    return mean_square_difference(q_i, q_j) < rho


@njit(cache=True, inline="always")
def merge_profiles(q_i: np.ndarray, q_j: np.ndarray, out: np.ndarray) -> None:
    """The paper (Merging, docs/explanation/paper.md#merging): the merged cell's profile ``(Q[i] + Q[j]) / 2`` into ``out`` (which may be ``q_i``)."""
    for a in range(q_i.shape[0]):
        out[a] = (q_i[a] + q_j[a]) / 2.0


# -- Beyond the paper ------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def repeat_limit_reached(repeats: int, max_repeat: int) -> bool:
    """``max_repeat``: a decision repeated that many primitive steps ends in its own cell (0: no limit)."""
    return max_repeat > 0 and repeats >= max_repeat


@njit(cache=True, inline="always")
def reward_jump(r: float, prev_r: float, steps_in_episode: int, r_trigger: float) -> bool:
    """``reward_trigger``: grow where the reward changes by at least ``r_trigger`` from one step to the
    next (never on an episode's first step)."""
    return steps_in_episode > 1 and abs(r - prev_r) >= r_trigger


@njit(cache=True, inline="always")
def value_jump(delta: float, v_trigger: float) -> bool:
    """``value_trigger`` (the paper's optional trigger, docs/explanation/paper.md#growing): grow where the TD error reaches
    ``v_trigger`` in size (0: off)."""
    return v_trigger > 0.0 and abs(delta) >= v_trigger


@njit(cache=True, inline="always")
def collision_split(dist_to_own: float, a_is_greedy: bool, q_ia: float, chi: float) -> bool:
    """``collision_split``: where the paper's collision rule (docs/explanation/paper.md#growing) would set ``Q[i, a] = chi`` for the whole cell, split ``x`` off
    instead when ``a`` is still the cell's greedy action (worth more than ``chi``) and ``x`` is not the
    cell's own vector: the wall is in one part of the cell, not all of it."""
    return dist_to_own > 0.0 and a_is_greedy and q_ia > chi


@njit(cache=True, inline="always")
def closes_cycle(prev_cell: int, cell: int, next_cell: int) -> bool:
    """``cycle_split``: two decisions led from ``next_cell`` to ``cell`` and straight back into it, a cycle
    that the greedy policy repeats for ever while the cells' values hold. (Each agent adds which
    decisions count: greedy ones for Sarsa, known ones for the planner.)"""
    return next_cell == prev_cell and next_cell != cell


@njit(cache=True, inline="always")
def stayed_too_long(steps_in_decision: int, split_after: int, dist2_to_nearest: float, d_min: float) -> bool:
    """``split_after``: a decision that has stayed ``split_after`` steps in its cell while the observation
    lies farther than ``d_min`` from every vector: the cell is too large for one decision there (0: off)."""
    return split_after > 0 and steps_in_decision >= split_after and dist2_to_nearest > d_min * d_min


@njit(cache=True, inline="always")
def outcome_disagrees(excess: float, split_threshold: float) -> bool:
    """``outcome_split``: a decision's outcome disagrees with what it led to before by more than
    ``split_threshold`` beyond what the distance between their starts explains (``excess``)."""
    return excess > split_threshold


@njit(cache=True, inline="always")
def split_matters(worse_outcome: float, next_best: float) -> bool:
    """``outcome_split``: splitting must matter to the policy: the worse of the two outcomes falls below
    the value of the cell's next best decision."""
    return worse_outcome < next_best


@njit(cache=True, inline="always")
def old_enough(episodes: int, born_i: int, born_j: int, merge_age: int) -> bool:
    """``merge_age``: both cells have lived ``merge_age`` complete episodes since the one that made them
    (0: no guard)."""
    return merge_age <= 0 or (episodes - born_i >= merge_age and episodes - born_j >= merge_age)


@njit(cache=True, inline="always")
def same_greedy_action(q_i: np.ndarray, q_j: np.ndarray) -> bool:
    """``merge_same_action``: two cells whose greedy actions agree (the first best of each)."""
    return np.argmax(q_i) == np.argmax(q_j)


@njit(cache=True, inline="always")
def stale_cell(episodes: int, born: int, last_decision: int, prune_after: int) -> bool:
    """``prune_after``: a cell older than ``prune_after`` episodes in which no decision was taken for the
    last ``prune_after`` episodes."""
    return episodes - born >= prune_after and episodes - last_decision >= prune_after


@njit(cache=True, inline="always")
def merged_decision_leaves(exits: int, known: int) -> bool:
    """``rho`` of the planning agent (merging under a model): two cells may merge only if the greedy decision of
    each would leave the merged cell in what was seen, at least ``known`` of its transitions (``exits``) ending
    outside it. The paper values a decision that cannot leave its cell at ``chi``; a merge that would make the
    greedy decision such a one is refused."""
    return exits >= known
