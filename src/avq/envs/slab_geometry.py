"""The slab maze's geometry (:class:`~avq.envs.slab_maze.SlabMaze`): slabs, the move kernel, mazes drawn from a
seed, and the check that a maze leads to its goal.

A slab is a wall of no thickness perpendicular to one axis of the unit cube ``[0, 1]^d``, at a
``position`` on that axis, spanning the whole cube except its opening: the closed box
``low[k] <= x[k] <= high[k]`` over the other axes ``k``. A slab separates the points with
``x[axis] < position`` from those with ``x[axis] >= position``. The slabs are kept as four arrays
(:class:`Slabs`), with the opening's bounds on the slab's own axis set to -inf and +inf, so that the
compiled move (:func:`slab_move`) tests an opening with one loop over all axes.

The slabs cut the cube into regions: along each axis, the slices between consecutive slabs of that axis;
a region is a box, one slice on every axis. As slabs on one axis are at least ``move`` apart and from the
cube's faces, every slice is at least ``move`` thick: inside a region every point of the lattice of moves
through a start is reachable, and a move across a slab lands in the neighbouring region.
:func:`regions_reaching_goal` searches those regions (not the ``ceil(1 / move)^d`` lattice points).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import reduce
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from avq.envs.grid_maze import BUMP_REWARD, GOAL_REWARD, MOVE_REWARD

__all__ = [
    "Slabs", "slab_move", "parse_slabs", "draw_slabs", "regions_reaching_goal", "unreachable_message",
    "lattice_distances", "in_goal", "EPS",
]  # fmt: skip

#: Rounding tolerance of the width of an opening and of a lattice of moves (positions are sums of moves).
EPS = 1e-9


class Slabs(NamedTuple):
    """The slabs of a maze as arrays (``n`` slabs in ``d`` dimensions), sorted by axis and position.

    Attributes:
        axis: ``(n,)`` int64, the axis each slab is perpendicular to.
        position: ``(n,)`` float64, where it crosses that axis.
        low, high: ``(n, d)`` float64, the opening's corners; -inf and +inf on the slab's own axis.
    """

    axis: np.ndarray
    position: np.ndarray
    low: np.ndarray
    high: np.ndarray

    def specs(self) -> list[tuple[int, float, tuple[float, ...], tuple[float, ...]]]:
        """The slabs as ``SlabMaze(walls=...)`` takes them: ``(axis, position, low, high)``, with 0 and 1 for
        the opening's bounds on the slab's own axis."""
        low, high = np.clip(self.low, 0.0, 1.0), np.clip(self.high, 0.0, 1.0)
        return [
            (int(a), float(p), tuple(map(float, lo)), tuple(map(float, hi)))
            for a, p, lo, hi in zip(self.axis, self.position, low, high)
        ]


@njit(cache=True)
def slab_move(
    pos: np.ndarray, axis: int, delta: float, slabs: Slabs, goal_low: float
) -> tuple[float, bool, bool]:  # pragma: no cover  (compiled)
    """One move of ``delta`` along ``axis`` from ``pos`` (changed in place): ``(reward, terminated, collision)``.

    Leaving the cube, or crossing a slab (changing side of its plane) outside its opening (tested at the
    point's other coordinates, which the move does not change), is a collision: ``pos`` stays, -10.
    Otherwise the point moves: -1, or +10 and the end when every coordinate is at least ``goal_low``.
    """
    old = pos[axis]
    new = old + delta
    if new < 0.0 or new > 1.0:
        return BUMP_REWARD, False, True
    for s in range(slabs.axis.shape[0]):
        c = slabs.position[s]
        if slabs.axis[s] == axis and (old < c) != (new < c):
            for k in range(pos.shape[0]):
                if pos[k] < slabs.low[s, k] or pos[k] > slabs.high[s, k]:
                    return BUMP_REWARD, False, True
    pos[axis] = new
    if in_goal(pos, goal_low):
        return GOAL_REWARD, True, False
    return MOVE_REWARD, False, False


@njit(cache=True)
def in_goal(pos: np.ndarray, goal_low: float) -> bool:  # pragma: no cover  (compiled)
    """Whether ``pos`` is in the goal: every coordinate at least ``goal_low``."""
    k, n = 0, pos.shape[0]
    while k < n and pos[k] >= goal_low:  # (a loop: no array made at every step)
        k += 1
    return k == n


@njit(cache=True)
def lattice_distances(
    origin: np.ndarray, counts: np.ndarray, source: int, move: float, slabs: Slabs, goal_low: float
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover  (compiled)
    """Least moves from the lattice point ``source`` to every point of a lattice of moves, and which points are in
    the goal: ``(distances, goal)``, flat arrays, -1 where no walk from ``source`` gets.

    The lattice has ``counts[k]`` points on axis ``k``, at ``origin[k] + j * move``; a point's flat index is its
    row-major index (``np.ravel_multi_index`` over ``counts``). A breadth-first search whose moves are
    :func:`slab_move`'s, so they collide where a step from those coordinates would, and whose walks end in the goal
    (:func:`in_goal`), as an episode does: a point of the goal reached only through the goal is -1.
    """
    d, n = counts.shape[0], 1
    for k in range(d):
        n *= counts[k]
    stride = np.ones(d, dtype=np.int64)
    for k in range(d - 2, -1, -1):
        stride[k] = stride[k + 1] * counts[k + 1]
    dist = np.full(n, -1, dtype=np.int64)
    goal = np.zeros(n, dtype=np.bool_)
    queue = np.empty(n, dtype=np.int64)
    dist[source], queue[0] = 0, source
    head, tail = 0, 1
    pos, start, index = np.empty(d), np.empty(d), np.empty(d, dtype=np.int64)
    while head < tail:
        q = queue[head]
        head += 1
        for k in range(d):
            index[k] = (q // stride[k]) % counts[k]
            start[k] = origin[k] + index[k] * move
        if in_goal(start, goal_low):
            goal[q] = True
            continue  # (the walk ends there)
        for a in range(2 * d):
            k, step = a >> 1, 1 - 2 * (a & 1)
            j = index[k] + step
            if j < 0 or j >= counts[k]:
                continue  # (leaves the lattice, which ends within a move of the cube's faces: a collision)
            pos[:] = start
            if slab_move(pos, k, step * move, slabs, goal_low)[2]:
                continue
            r = q + step * stride[k]
            if dist[r] < 0:
                dist[r] = dist[q] + 1
                queue[tail] = r
                tail += 1
    return dist, goal


def _slabs(dims: int, axis: list[int], position: list[float], low: np.ndarray, high: np.ndarray) -> Slabs:
    ax, pos = np.asarray(axis, dtype=np.int64), np.asarray(position, dtype=np.float64)
    lo, hi = np.array(low, dtype=np.float64).reshape(-1, dims), np.array(high, dtype=np.float64).reshape(-1, dims)
    lo[np.arange(len(ax)), ax], hi[np.arange(len(ax)), ax] = -np.inf, np.inf
    order = np.lexsort((pos, ax))
    arrays = [ax[order], pos[order], lo[order], hi[order]]
    for a in arrays:
        a.setflags(write=False)
    return Slabs(*arrays)


def parse_slabs(walls: Sequence[Any], dims: int, move: float, goal_size: float) -> Slabs:
    """Check a list of slab specifications ``(axis, position, low, high)`` and make :class:`Slabs` of it.

    ``low`` and ``high`` are ``dims`` numbers in [0, 1] each (the entries on the slab's own axis are
    ignored); every position is in ``[move, 1 - goal_size]`` and slabs on one axis are ``move`` apart.
    """
    axis: list[int] = []
    position: list[float] = []
    low, high = [], []
    last = 1.0 - goal_size
    for j, spec in enumerate(walls):
        try:
            a, p, lo, hi = spec
            lo, hi = [float(v) for v in lo], [float(v) for v in hi]
            p = float(p)
        except (TypeError, ValueError):
            raise ValueError(
                f"walls[{j}] must be a slab (axis, position, low, high), low and high the opening's corners "
                f"({dims} numbers each), not {spec!r}"
            ) from None
        if isinstance(a, bool) or not isinstance(a, (int, np.integer)) or not 0 <= a < dims:
            raise ValueError(
                f"walls[{j}] has axis {a!r}, but dims={dims} has axes 0 to {dims - 1}; give an axis below dims (or raise dims)"
            )
        if len(lo) != dims or len(hi) != dims:
            raise ValueError(
                f"walls[{j}]: the opening's corners must have {dims} numbers each (one per axis), not {len(lo)} and {len(hi)}"
            )
        if not move - EPS <= p <= last + EPS:
            raise ValueError(
                f"walls[{j}] at position {p} on axis {a}: slabs must lie in [move, 1 - goal_size] = [{move}, {last}], "
                "so that every slice is at least one move thick and the goal lies beyond every slab; move it inside"
            )
        other = [k for k in range(dims) if k != a]
        if not all(0.0 <= lo[k] <= hi[k] <= 1.0 for k in other):
            raise ValueError(
                f"walls[{j}]: its opening from {tuple(lo)} to {tuple(hi)} must have 0 <= low <= high <= 1 on every "
                f"axis but its own ({a}); swap or clip the corners"
            )
        axis.append(int(a))
        position.append(p)
        low.append(lo)
        high.append(hi)
    slabs = _slabs(dims, axis, position, np.array(low), np.array(high))
    for s in range(len(slabs.axis) - 1):
        same = slabs.axis[s] == slabs.axis[s + 1]
        if same and slabs.position[s + 1] - slabs.position[s] < move - EPS:
            raise ValueError(
                f"two slabs on axis {slabs.axis[s]}, at {slabs.position[s]} and {slabs.position[s + 1]}, are closer "
                f"than move={move}: one move could cross both; put slabs on one axis at least move apart"
            )
    return slabs


def draw_slabs(n: int, dims: int, opening: float, move: float, goal_size: float, seed: int) -> Slabs:
    """``n`` slabs drawn from ``seed``, every region of whose cube leads to the goal.

    Slab ``j`` is perpendicular to axis ``j % dims``. The slabs of an axis split ``[move, 1 - goal_size]``
    into equal bins, one slab a bin at a uniform place at least ``move`` before the bin's end. The axes are
    put in a random order, the order in which a path passes their slabs: an opening is ``opening`` wide on
    every other axis, at a uniform place such that it overlaps by at least ``move`` the last slice of an axis
    passed before (near the goal), and every slice of an axis passed after (wider than ``opening`` where it
    must span several slabs of that axis). So from any region the goal is reached by passing the slabs axis
    by axis in that order, whatever the draw.
    """
    rng = np.random.default_rng(seed)
    counts = np.bincount(np.arange(n) % dims, minlength=dims)
    span = 1.0 - goal_size - move
    if n and span / counts.max() < move - EPS:
        fit = math.floor(span / move + EPS)
        raise ValueError(
            f"walls={n} puts {counts.max()} slabs on axis 0, but only {fit} fit between move={move} and "
            f"1 - goal_size={1.0 - goal_size} at least a move apart; use at most {fit * dims} walls or a smaller move"
        )
    cuts = [move + (np.arange(m) + rng.random(m) * (1.0 - move * m / span)) * span / m for m in counts]
    rank = np.argsort(rng.permutation(dims))  # (rank[k]: when the path passes the slabs of axis k)
    axis = np.repeat(np.arange(dims), counts)
    low, high = np.zeros((n, dims)), np.ones((n, dims))
    for s, i in enumerate(axis):
        for k in range(dims):
            c, width = cuts[k], opening
            if k == i:
                continue
            if not len(c):  # (no slab across axis k: anywhere)
                first, last = 0.0, 1.0 - width
            elif rank[k] < rank[i]:  # (passed before: overlap the last slice)
                first, last = max(0.0, c[-1] + move - width), 1.0 - width
            else:  # (passed after: overlap every slice)
                width = max(width, c[-1] - c[0] + 2.0 * move)
                first, last = max(0.0, c[-1] + move - width), min(c[0] - move, 1.0 - width)
            low[s, k] = first + rng.random() * (last - first)
            high[s, k] = low[s, k] + width
    slabs = _slabs(dims, list(axis), list(np.concatenate(cuts)), low, high)
    assert regions_reaching_goal(slabs, dims, move).all(), "a drawn maze leads to the goal from every region"
    return slabs


def _cuts(slabs: Slabs, dims: int) -> list[np.ndarray]:
    """The slice boundaries on every axis: 0, the slabs' positions, 1."""
    return [np.concatenate(([0.0], slabs.position[slabs.axis == k], [1.0])) for k in range(dims)]


def regions_reaching_goal(slabs: Slabs, dims: int, move: float) -> np.ndarray:
    """Which regions lead to the goal: a boolean array, one entry per region (slice indices on every axis).

    The goal lies in the last region (:func:`parse_slabs` and :func:`draw_slabs` keep every slab at or below
    ``1 - goal_size``). A slab lets a point pass
    between the two regions on its sides where its opening overlaps the regions' common face by at least
    ``move`` on every other axis: there every lattice of moves has a point, whatever the start. The search
    counts only those passages, so it is exact for what it claims (from a region it marks, the goal is
    reachable from every start) and cautious otherwise: a maze connected only through narrower gaps, which
    some starts could miss, is refused.
    """
    cuts = _cuts(slabs, dims)
    reached = np.zeros([len(c) - 1 for c in cuts], dtype=np.bool_)
    reached[(-1,) * dims] = True
    doors = []
    for s in range(len(slabs.axis)):
        i = int(slabs.axis[s])
        m = int(np.searchsorted(cuts[i], slabs.position[s])) - 1  # (the slice below it: cuts[i][m + 1] is the slab)
        wide = [
            np.minimum(slabs.high[s, k], cuts[k][1:]) - np.maximum(slabs.low[s, k], cuts[k][:-1]) >= move - EPS
            for k in range(dims)
            if k != i
        ]
        door = reduce(np.multiply.outer, wide) if wide else np.bool_(True)
        before = (slice(None),) * i
        doors.append((before + (m,), before + (m + 1,), door))
    count = -1
    while count != reached.sum():
        count = reached.sum()
        for below, above, door in doors:
            through = (reached[below] | reached[above]) & door
            reached[below] |= through
            reached[above] |= through
    return reached


def unreachable_message(slabs: Slabs, dims: int, reached: np.ndarray, move: float) -> str:
    """The first region of ``reached`` that does not reach the goal, in words: ``x[0] in [0, 0.4), x[1] in [0.5, 1]``."""
    cuts = _cuts(slabs, dims)
    index = np.argwhere(~reached)[0]
    where = ", ".join(
        f"x[{k}] in [{cuts[k][j]:.3g}, {cuts[k][j + 1]:.3g}{']' if j == len(cuts[k]) - 2 else ')'}"
        for k, j in enumerate(index)
        if len(cuts[k]) > 2
    )
    return (
        f"the walls leave no path to the goal from the region {where}: no chain of openings at least move={move} "
        "wide (on every axis but the slab's own, where it meets a region) leads from there; widen or move an opening"
    )
