"""Dimensions of an observation that are noise: no decision can follow them, so a metric should not count them.

A dimension is *noise* when its next value is not predictable from the observation before it: a linear
prediction of ``x[t + 1, k]`` from the whole vector ``x[t]`` (with an intercept, by least squares over the pairs
of consecutive observations of one episode) explains less than :data:`NOISE_R2` of its variance. A value drawn
afresh at every step (``avq.envs.IrrelevantDims(kind="noise")``) explains about ``(n + 1) / pairs`` of it by
chance (1% over 1,000 pairs of 12 dimensions); the dimensions of the tasks measured explain at least 45%, down to
the fast-spinning links of Acrobot-v1 and the legs' contacts of LunarLander-v3 (docs/results/dimensions.md,
Irrelevant dimensions). A dimension that drifts slowly without mattering (``kind="walk"``) is predictable and is
not found here.

The agents of :class:`avq.agents._spaces.ScaledMetric` with ``ignore_noise`` keep the first ``scale_warmup``
observations (:class:`avq.agents._spaces.RunningSpread` with ``log``) and, once they have them all, give the noise dimensions an infinite scale
(weight 0 in the distance).
"""

from __future__ import annotations

import numpy as np

__all__ = ["NOISE_R2", "noise_dims"]

#: The share of a dimension's variance below which a linear prediction from the previous observation marks it as
#: noise (:func:`noise_dims`).
NOISE_R2 = 0.1


def noise_dims(obs: np.ndarray, follows: np.ndarray) -> np.ndarray:
    """Which dimensions of the observations ``obs`` (``(t, n)``) are noise (module docstring): a bool per dimension.

    ``follows[s]`` says whether ``obs[s]`` came one step after ``obs[s - 1]`` in the same episode (``follows[0]`` is
    ignored). With fewer than ``2 * (n + 1)`` such pairs nothing is noise; nor is a dimension that never varied
    among the pairs' second observations.
    """
    obs = np.asarray(obs, dtype=np.float64)
    n = obs.shape[1]
    after = np.flatnonzero(np.asarray(follows, dtype=bool)[1:]) + 1
    if after.size < 2 * (n + 1):
        return np.zeros(n, dtype=bool)
    before = np.column_stack([obs[after - 1], np.ones(after.size)])
    target = obs[after]
    coef, *_ = np.linalg.lstsq(before, target, rcond=None)
    residual = (target - before @ coef).var(axis=0)
    variance = target.var(axis=0)
    varied = variance > 1e-12 * np.maximum(1.0, np.abs(target).max(axis=0)) ** 2
    explained = 1.0 - residual / np.where(varied, variance, 1.0)
    return varied & (explained < NOISE_R2)
