"""What ``avq-plan``'s kernels read and write: the record of the agent's arrays, its parameters (declared
once) and the indices of its state.

The kernels (:mod:`avq.agents.plan.kernels`, :mod:`avq.agents.plan.memory`) take two records: ``ag``, a
:class:`PlanArrays` (the codebook, the parameters, the state, the remembered transitions), and ``m``,
the model's :class:`~avq.agents.plan.model.ModelArrays`; both are NamedTuples of arrays, which Numba
takes as they are.

The state arrays: ``S`` int and ``F`` float state (index names below; ``S[GEOM]`` counts the changes of
the codebook, so that a caller may keep the cells of observations it sees again). ``F`` holds the
current transition's return and discount, the episode's return, and the sums that estimate the value's
slope (return per unit of scaled distance travelled, and how many); then ``n + 1`` entries of scratch
(``F`` has ``N_F + n + 1`` entries).
"""

from __future__ import annotations

from enum import auto
from typing import Any, NamedTuple

import numpy as np
from scipy.signal import lfilter

from avq._numba import borrowed_record
from avq.agents._params import ParamIndex

__all__ = [
    "PlanArrays",
    "PlanParam",
    "PlanIntParam",
    "auto_v_opt",
    "best_return_to_go",
    "borrowed_plan",
    "horizon",
    "load_cells",
    "load_state_arrays",
    "no_neighbours",
    "value_ceiling",
]


class PlanParam(ParamIndex):
    """``P``: the float parameters, each named after the agent parameter it holds."""

    GAMMA = auto()
    EPSILON = auto()
    D_MIN = auto()  # growth: no vector within d_min of another
    SPLIT_THRESHOLD = auto()  # outcome_split's excess
    VALUE_SLOPE = auto()  # outcome_split's slope; -1: estimated (value_slope=None)
    RHO = auto()  # merging: the largest mean square difference of two cells' profiles; -1: off (rho=None)
    KNOWN_RADIUS = auto()  # decisions: optimism for a decision never tried within it; -1: off (known_radius=None)
    AXIS_SHARE = auto()  # the outcome split's cut across one axis; -1: never (axis_share=None)


class PlanIntParam(ParamIndex):
    """``IP``: the int parameters (switches as 0 or 1), each named after the agent parameter it holds."""

    MAX_CELLS = auto()
    N_BACKUPS = auto()  # the planner's budget per transition
    COLLISION_GROWTH = auto()
    OUTCOME_SPLIT = auto()
    MEMORY = auto()  # remembered transitions
    CYCLE_SPLIT = auto()
    SPLIT_AFTER = auto()  # 0: off (split_after=None)
    MERGE_NEIGHBOURS = auto()  # merging: each cell's nearest cells among which its partner is sought
    MERGE_SAME_ACTION = auto()  # merging: only cells whose greedy actions agree
    COLLISION_CUT = auto()  # growth: a collision cuts its cell across one axis (collision_cut)
    COMPOSE_CROSSINGS = auto()  # crossings remembered: 0 no; memory.COMPOSED (compose_crossings, rho); memory.HELD
    FINER_WHEN_SETTLED = auto()  # how many times the floor of the growth from decisions may halve


# S: int state
SIZE, CELL, ACTION, EP_STEPS, APPENDS, REFUSED, DECISIONS, IN_EPISODE, MEM_N, MEM_POS, SPLITS, GEOM = range(12)
PREV_CELL, PREV_KNOWN = 12, 13  # the cell of the decision before the current one (-1 at an episode's start),
# and whether that decision was of a known pair
DEC_STEPS = 14  # the primitive steps taken so far with the current decision
DEC_REFUSED = 15  # whether split_after's growth was refused during the current decision (counted once)
MERGES = 16  # cells merged at the end of the current episode
FINER = 17  # times the floor of the growth from decisions has halved (finer_when_settled; avq.agents.plan.resolution)
N_S = 18
# F: float state
RET, DISC, EP_RETURN, SLOPE_SUM, SLOPE_N = range(5)
N_F = 5
#: What an episode's start sets (:func:`avq.agents.plan.kernels.start`), as ``(index, value)`` pairs: in S the
#: episode's counters, then the decision before the first (none) and the current one's; in F the transition's
#: return and discount and the episode's return.
S_AT_START: tuple[tuple[int, int], ...] = ((EP_STEPS, 0), (APPENDS, 0), (REFUSED, 0), (SPLITS, 0), (MERGES, 0))
S_AT_START += ((DECISIONS, 1), (IN_EPISODE, 1), (PREV_CELL, -1), (PREV_KNOWN, 0), (DEC_STEPS, 0), (DEC_REFUSED, 0))
F_AT_START = ((RET, 0.0), (DISC, 1.0), (EP_RETURN, 0.0))


class PlanArrays(NamedTuple):
    """``avq-plan``'s own arrays, as its kernels take them (one argument, ``ag``)."""

    #: ``(cap, n)`` the codebook (its first ``S[SIZE]`` rows), in observation units.
    V: np.ndarray
    #: ``(n,)`` one over the metric's scale.
    inv_scale: np.ndarray
    #: Float parameters (:class:`PlanParam`) and int parameters (:class:`PlanIntParam`).
    P: np.ndarray
    IP: np.ndarray
    #: Int and float state (the indices above).
    S: np.ndarray
    F: np.ndarray
    #: ``(n,)`` the observation that started the current transition.
    xs: np.ndarray
    #: The memory: ``(M, 2n)`` start and end observations, ``(M, 4)`` action, start cell, end cell (-1:
    #: terminal) and whether it ended only because the cell changed (1, else 0; only with merging on, ``rho``),
    #: ``(M, 2)`` return and discount.
    mem_x: np.ndarray
    mem_i: np.ndarray
    mem_f: np.ndarray
    #: ``(edges, n)`` the sum of the starts of each edge's transitions (the edges of the model).
    e_xs: np.ndarray
    #: ``(cap + 1, merge_neighbours)`` the merge pass's neighbours: ``near[1 + i]`` lists cell ``i``'s nearest
    #: cells, nearest first, found for the codebook of ``S[GEOM] == near[0, 0]`` (-1: not yet). Derived, not saved.
    near: np.ndarray


def no_neighbours(cap: int, k: int) -> np.ndarray:
    """The merge pass's neighbour table for ``cap`` cells, not yet found (:class:`PlanArrays`' ``near``)."""
    return np.full((cap + 1, k), -1, dtype=np.int64)


#: Arrays of a model file that grew since, and their last dimensions before: with merging (avq 0.2) and
#: finer_when_settled.
_GREW = {"S": (16, 17), "mem_i": (3,)}


def load_state_arrays(ag: PlanArrays, arrays: dict[str, np.ndarray]) -> None:
    """Copy a saved agent's state and memory (``S``, ``F``, ``xs``, ``mem_x``, ``mem_i``, ``mem_f``) into ``ag``'s
    arrays of the same shapes; a file from before, whose ``S`` or ``mem_i`` was narrower (``_GREW``), gets 0 in the
    entries added since. Raises ValueError for an array of another shape."""
    for name in ("S", "F", "xs", "mem_x", "mem_i", "mem_f"):
        mine, theirs = getattr(ag, name), arrays[name]
        if name in _GREW and theirs.shape[:-1] == mine.shape[:-1] and theirs.shape[-1] in _GREW[name]:
            mine[:] = 0
            mine[..., : theirs.shape[-1]] = theirs
            continue
        if theirs.shape != mine.shape:
            raise ValueError(f"array {name} has shape {theirs.shape}; expected {mine.shape}")
        mine[:] = theirs


def load_cells(ag: PlanArrays, codebook: np.ndarray, e_xs: np.ndarray, edges: int) -> None:
    """Copy a saved agent's ``codebook`` and its edges' summed starts ``e_xs`` (``edges`` rows) into ``ag``'s
    arrays, which have room for them; the merge pass is to find the cells' neighbours again. Raises ValueError
    for ``e_xs`` of another shape."""
    if e_xs.shape != (edges, ag.xs.shape[0]):
        raise ValueError(f"array e_xs has shape {e_xs.shape}; expected ({edges}, {ag.xs.shape[0]})")
    ag.V[: len(codebook)] = codebook
    ag.near[0, 0] = -1
    ag.e_xs[: len(e_xs)] = e_xs


#: ``borrowed_plan(ag)``: ``ag`` with its arrays as borrowed views (:func:`avq._numba.borrowed_record`), for a
#: fused loop's own use.
borrowed_plan = borrowed_record


#: The horizon of ``v_opt="auto"`` on a task with ``gamma = 1`` and no time limit.
UNLIMITED_HORIZON = 1000


def horizon(env: Any, gamma: float) -> float:
    """What ``v_opt="auto"`` multiplies the largest reward by: the discounted number of steps an episode may
    last, ``1 + gamma + ... + gamma ** (L - 1)`` for the environment's time limit ``L``
    (``env.spec.max_episode_steps``; ``L`` itself with ``gamma = 1``); without a limit ``1 / (1 - gamma)``, or
    :data:`UNLIMITED_HORIZON` with ``gamma = 1``."""
    spec = getattr(env, "spec", None)
    limit = getattr(spec, "max_episode_steps", None)
    if gamma == 1.0:
        return float(limit) if limit else float(UNLIMITED_HORIZON)
    return (1.0 - gamma**limit) / (1.0 - gamma) if limit else 1.0 / (1.0 - gamma)


def auto_v_opt(horizon: float, r_min: float, r_max: float) -> float:
    """``v_opt="auto"`` after rewards from ``r_min`` to ``r_max`` (``inf`` and ``-inf`` before any): where no reward
    below 0 has been seen, R-max's bound, ``horizon`` times the largest reward (0 while none is above 0);
    once rewards of both signs have been (shaped rewards, where that bound is off by orders of magnitude), and
    where every reward is a cost, 0: an untried decision is worth ending the episode with nothing more
    (docs/results/dimensions.md, Optimism on shaped rewards)."""
    return 0.0 if r_min < 0.0 else horizon * max(0.0, r_max)


def value_ceiling(r_min: float, r_max: float, to_go_max: float) -> float:
    """The ceiling of every planned value with ``v_opt="auto"`` (``inf``: none): once rewards of both signs have
    been seen, the largest return from any step of an episode to its end seen so far (``to_go_max``; no lower
    than 0, the value of an untried decision then). On shaped rewards an aggregated model holds loops at a gain
    that the task does not have (a cell's states do not share its loops), and without a ceiling their planned
    values grow without end (docs/results/dimensions.md, Optimism on shaped rewards)."""
    return max(0.0, to_go_max) if r_min < 0.0 < r_max else np.inf


def best_return_to_go(rewards: Any, gamma: float) -> float:
    """The largest discounted return from any step of an episode (its ``rewards`` in order) to its end; ``-inf``
    for an episode without rewards."""
    if len(rewards) == 0:
        return -np.inf
    return float(lfilter([1.0], [1.0, -gamma], np.asarray(rewards, dtype=np.float64)[::-1]).max())
