"""The action codebook's rules, on unit-scaled action vectors: growth next to the most used action, merging
of neighbours whose value columns agree (the paper's growing and merging, docs/explanation/paper.md#growing
and #merging, with states and actions swapped). Pure functions of vectors and value columns, which
:class:`~avq.agents.actions.agent.ActionCodebookSarsa` applies."""

from __future__ import annotations

import numpy as np

__all__ = ["gabriel_neighbours", "merged_vector", "plan_growth", "plan_merges", "uniform_actions"]


def uniform_actions(k: int, dims: int) -> np.ndarray:
    """A uniform grid of ``k`` points per dimension over the unit box, ``(k ** dims, dims)``,
    the first dimension varying slowest (``k = 1``: the centre)."""
    axis = np.array([0.5]) if k == 1 else np.linspace(0.0, 1.0, k)
    mesh = np.meshgrid(*([axis] * dims), indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def gabriel_neighbours(points: np.ndarray, i: int) -> list[int]:
    """The vectors adjacent to ``points[i]``: ``j`` such that no other vector lies strictly
    inside the ball whose diameter is the segment ``i``-``j`` (the Gabriel graph; in one
    dimension, the vectors just left and right of ``i``)."""
    out = []
    for j in range(len(points)):
        if j == i:
            continue
        centre = (points[i] + points[j]) / 2.0
        radius2 = float(np.sum((points[i] - centre) ** 2))
        others = np.delete(np.arange(len(points)), [i, j])
        if not np.any(np.sum((points[others] - centre) ** 2, axis=1) < radius2):
            out.append(j)
    return out


def plan_growth(points: np.ndarray, q: np.ndarray, d_min: float) -> tuple[int, int] | None:
    """Where to split: ``(g, j)`` to insert ``(points[g] + points[j]) / 2``, or None.

    Args:
        points: ``(n, d)`` live action vectors in unit coordinates.
        q: ``(N, n)`` action values of ``N`` recently visited states.
        d_min: Smallest allowed distance of a new vector to every existing one.

    ``g`` is the action that is greedy (lowest index on ties) in the most states
    (lowest index on ties). Its neighbours (:func:`gabriel_neighbours`) are tried in
    order of their mean value over the states where ``g`` is greedy, best first
    (lowest index on ties); the first whose midpoint lies farther than ``d_min``
    from every vector is chosen. None when every midpoint is too close.
    """
    n = points.shape[0]
    if n < 2 or q.shape[0] == 0:
        return None
    greedy = q.argmax(axis=1)
    g = int(np.bincount(greedy, minlength=n).argmax())
    where_g = q[greedy == g]
    neighbours = gabriel_neighbours(points, g)
    values = where_g[:, neighbours].mean(axis=0)
    for k in np.argsort(-values, kind="stable"):
        j = neighbours[int(k)]
        mid = (points[g] + points[j]) / 2.0
        if np.sqrt(np.sum((points - mid) ** 2, axis=1)).min() > d_min:
            return g, j
    return None


def plan_merges(points: np.ndarray, q: np.ndarray, rho: float, min_actions: int = 2) -> list[tuple[int, int]]:
    """The pairs to merge, ``(i, j)`` with ``i < j``, most similar first.

    A pair merges when its vectors are each other's nearest (lowest index on ties)
    and the mean square difference of their value columns over the ``N`` states,
    ``mean_s (q[s, i] - q[s, j]) ** 2``, is below ``rho`` (docs/explanation/paper.md#merging with the roles of
    states and actions swapped). Mutual nearest pairs are disjoint. Merging stops
    before fewer than ``min_actions`` vectors would be left.
    """
    n = points.shape[0]
    if n < 2 or q.shape[0] == 0:
        return []
    d2 = np.sum((points[:, None, :] - points[None, :, :]) ** 2, axis=2)
    np.fill_diagonal(d2, np.inf)
    nearest = d2.argmin(axis=1)
    pairs = []
    for i in range(n):
        j = int(nearest[i])
        if i < j and nearest[j] == i:
            msd = float(np.mean((q[:, i] - q[:, j]) ** 2))
            if msd < rho:
                pairs.append((msd, i, j))
    pairs.sort()
    return [(i, j) for _, i, j in pairs[: max(0, n - min_actions)]]


def merged_vector(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The mean of two unit-scaled vectors, except that a coordinate on the box's edge
    (0 or 1) in one of them and not the other stays on that edge.

    Plain averaging could only ever pull the codebook inward: the extreme actions
    (often the best ones, as in bang-bang control) would be lost for good, since
    growth inserts midpoints only.
    """
    out = (a + b) / 2.0
    for v in (a, b):
        edge = (v == 0.0) | (v == 1.0)
        other = b if v is a else a
        keep = edge & ~((other == 0.0) | (other == 1.0))
        out[keep] = v[keep]
    return out
