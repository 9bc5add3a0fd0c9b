"""Dimensions of an observation that are noise: no decision can follow them, so a metric should not count them.

A dimension is *noise* when its next value is not predictable from the observation before it: a linear
prediction of ``x[t + 1, k]`` from the whole vector ``x[t]`` (with an intercept, by least squares over the pairs
of consecutive observations of one episode) explains less than :data:`NOISE_R2` of its variance. A value drawn
afresh at every step (``avq.envs.IrrelevantDims(kind="noise")``) explains about ``(n + 1) / pairs`` of it by
chance (1% over 1,000 pairs of 12 dimensions); the dimensions of the tasks measured explain at least 45%, down to
the fast-spinning links of Acrobot-v1 and the legs' contacts of LunarLander-v3 (docs/results/dimensions.md,
Irrelevant dimensions). A dimension that drifts slowly without mattering (``kind="walk"``) is predictable and is
not found here.

A dimension drawn afresh at every step may still matter: a context that sets which action pays, or a gust that
moves the next state. So one that is unpredictable is noise only if it also explains nothing of what follows the
step beyond the rest of the observation and the action: where the actions and rewards are given, a dimension
whose products with the action (one column per action) explain at least :data:`RELEVANT_R2` of the variance that
the previous observation without it and the action leave in the reward, or in the next value of a dimension that
is not noise, is kept (:func:`matters`); so is one whose value after the step explains that share of the reward
(a leg that touches the ground: LunarLander-v3's contacts are rare in the first steps of some runs, and
unpredictable then). Appended noise explains about ``actions / pairs`` of either by chance.

The agents of :class:`avq.agents._spaces.ScaledMetric` with ``ignore_noise`` keep the first ``scale_warmup``
observations (:class:`avq.agents._spaces.RunningSpread` with ``log``) and, once they have them all, give the noise dimensions an infinite scale
(weight 0 in the distance).
"""

from __future__ import annotations

import numpy as np

__all__ = ["NOISE_R2", "RELEVANT_R2", "noise_dims", "matters"]

#: The share of a dimension's variance below which a linear prediction from the previous observation marks it as
#: noise (:func:`noise_dims`).
NOISE_R2 = 0.1
#: The share of what is left unexplained of the reward or of another dimension's next value that an unpredictable
#: dimension must explain, with the action, to be kept (:func:`matters`).
RELEVANT_R2 = 0.05


def noise_dims(
    obs: np.ndarray, follows: np.ndarray, actions: np.ndarray | None = None, rewards: np.ndarray | None = None
) -> np.ndarray:
    """Which dimensions of the observations ``obs`` (``(t, n)``) are noise (module docstring): a bool per dimension.

    ``follows[s]`` says whether ``obs[s]`` came one step after ``obs[s - 1]`` in the same episode (``follows[0]`` is
    ignored). With fewer than ``2 * (n + 1)`` such pairs nothing is noise; nor is a dimension that never varied
    among the pairs' second observations. ``actions[s]`` and ``rewards[s]``, where given, are the action taken in
    ``obs[s - 1]`` and the reward that came with ``obs[s]``: an unpredictable dimension that :func:`matters` to
    them is kept.
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
    noise = varied & (explained < NOISE_R2)
    if actions is not None and rewards is not None and noise.any():
        noise &= ~matters(obs, after, np.asarray(actions)[after], np.asarray(rewards, dtype=np.float64)[after], noise)
    return noise


def _left(columns: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The variance of each column of ``target`` that a least-squares fit on ``columns`` leaves unexplained."""
    coef, *_ = np.linalg.lstsq(columns, target, rcond=None)
    return (target - columns @ coef).var(axis=0)


def matters(
    obs: np.ndarray, after: np.ndarray, actions: np.ndarray, rewards: np.ndarray, noise: np.ndarray
) -> np.ndarray:
    """Which of the dimensions ``noise`` explain, with the action, at least :data:`RELEVANT_R2` of what the previous
    observation without them and the action leave unexplained of the reward or of the next value of a dimension
    that is not noise, or whose value after the step explains that share of the reward (the pairs
    ``obs[after - 1] -> obs[after]``; ``actions`` and ``rewards`` of those steps)."""
    _, which = np.unique(actions, return_inverse=True)
    one_hot = np.eye(int(which.max()) + 1)[which]
    before = obs[after - 1]
    target = np.column_stack([rewards, obs[after][:, ~noise]])
    kept = np.zeros(len(noise), dtype=bool)
    base = np.column_stack([one_hot, np.delete(before, np.flatnonzero(noise), axis=1)])
    left = _left(base, target)
    for j in np.flatnonzero(noise):
        with_j = _left(np.column_stack([base, one_hot * before[:, j : j + 1]]), target)
        # (the reward may also depend on the value the step led to: a leg that touches the ground)
        with_j[0] = min(with_j[0], _left(np.column_stack([base, obs[after, j]]), target[:, :1])[0])
        share = np.where(left > 1e-12, 1.0 - with_j / np.where(left > 1e-12, left, 1.0), 0.0)
        kept[j] = share.max() >= RELEVANT_R2
    return kept
