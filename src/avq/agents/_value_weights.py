"""Weights of a metric learned from the slopes of the values planned on it (``reweight_when_full``).

A dimension along which the value of the cells changes fast needs fine cells; one along which it hardly changes
needs few. Once enough cells have every decision known (:data:`MIN_CELLS`, and :data:`SETTLED_SHARE` of all the
cells), the planned value ``V`` of each is compared with that of its :data:`NEIGHBOURS` nearest (in the scaled
metric): the slope along each dimension is the non-negative least-squares fit of ``|V_i - V_j|`` to the distances
``|z_i[d] - z_j[d]|`` of all those pairs (:func:`value_slopes`). Each dimension is then weighted by its slope over
the largest, no less than :data:`FLOOR`, and the weights are divided by their geometric mean, so that the cells'
volume stays what ``scale`` made it (:func:`slope_weights`). On Acrobot-v1, with its 2,048 cells full, the two
velocities get weights of 1.4-1.9 and 3.7-4.2 and the angles' cosines 0.37-0.42: the direction its hand-made
entry weights (docs/results/dimensions.md, A metric weighted by the planned values).

:class:`avq.agents._spaces.ScaledMetric` applies the weights once, by dividing each dimension's scale (and the
factor that ``scale="auto"``'s estimates keep) by its weight.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_CELLS", "SETTLED_SHARE", "NEIGHBOURS", "FLOOR", "value_slopes", "slope_weights"]

#: Cells with every decision known (and a value above ``v_min``) needed before the slopes are fitted.
MIN_CELLS = 20
#: And the share of all the cells they must be: the fit describes the partition only where most cells are settled.
SETTLED_SHARE = 0.75
#: Each cell's nearest cells whose values it is compared with.
NEIGHBOURS = 5
#: The smallest weight, as a share of the largest: no dimension is left out of the metric by its slope alone.
FLOOR = 0.1


def value_slopes(z: np.ndarray, values: np.ndarray, neighbours: int = NEIGHBOURS) -> np.ndarray:
    """The value's slope along each dimension, ``>= 0``: the non-negative least-squares fit of ``|V_i - V_j|``
    to ``|z_i - z_j|`` (one column per dimension) over each point ``i`` of ``z`` (``(p, n)``, scaled) and its
    ``neighbours`` nearest ``j``. ``p`` must be at least 2."""
    from scipy.optimize import nnls
    from scipy.spatial import cKDTree

    z, values = np.asarray(z, dtype=np.float64), np.asarray(values, dtype=np.float64)
    k = min(neighbours, len(z) - 1)
    _, near = cKDTree(z).query(z, k=k + 1)
    near = near[:, 1:]  # (the nearest is the point itself)
    gaps = np.abs(z[:, None, :] - z[near]).reshape(-1, z.shape[1])
    change = np.abs(values[:, None] - values[near]).reshape(-1)
    slopes, _ = nnls(gaps, change)
    return slopes


def slope_weights(slopes: np.ndarray, floor: float = FLOOR) -> np.ndarray:
    """The weight of each dimension in the distance: its slope over the largest, at least ``floor``, divided by
    the geometric mean of them all (their product is 1). All ones where every slope is 0."""
    slopes = np.asarray(slopes, dtype=np.float64)
    top = slopes.max(initial=0.0)
    if top <= 0.0:
        return np.ones_like(slopes)
    w = np.maximum(slopes / top, floor)
    return w / np.exp(np.log(w).mean())
