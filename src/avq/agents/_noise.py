"""Dimensions of an observation that do not matter: noise, and dimensions that drift on their own. No decision can
follow them, so a metric should not count them.

A dimension is *noise* when its next value is not predictable from the observation before it: a linear
prediction of ``x[t + 1, k]`` from the whole vector ``x[t]`` (with an intercept, by least squares over the pairs
of consecutive observations of one episode) explains less than :data:`NOISE_R2` of its variance. A value drawn
afresh at every step (``avq.envs.IrrelevantDims(kind="noise")``) explains about ``(n + 1) / pairs`` of it by
chance (1% over 1,000 pairs of 12 dimensions); the dimensions of the tasks measured explain at least 45%, down to
the fast-spinning links of Acrobot-v1 and the legs' contacts of LunarLander-v3 (docs/results/dimensions.md,
Irrelevant dimensions).

A dimension drawn afresh at every step may still matter: a context that sets which action pays, or a gust that
moves the next state. So one that is unpredictable is noise only if it also explains nothing of what follows the
step beyond the rest of the observation and the action: where the actions and rewards are given, a dimension
whose products with the action (one column per action) explain at least :data:`RELEVANT_R2` of the variance that
the previous observation without it and the action leave in the reward, or in the next value of a dimension that
is not noise, is kept (:func:`matters`); so is one whose value after the step explains that share of the reward
(a leg that touches the ground: LunarLander-v3's contacts are rare in the first steps of some runs, and
unpredictable then). Appended noise explains about ``actions / pairs`` of either by chance.

A dimension that *drifts* (a slow random walk, ``kind="walk"``) is predictable, but its *change* is not
(:func:`drift_dims`). Whether it matters cannot be told from the first steps, over which it correlates by chance
with whatever else changes slowly; it can from a long log (:func:`drift_matters`, after :data:`JUDGE_AFTER`
observations). So a drifting dimension is left out with the noise, and counts again if it is then found to matter
(a wind that moves the position, a target whose distance is the reward).

The agents of :class:`avq.agents._spaces.ScaledMetric` with ``ignore_noise`` keep the first ``scale_warmup``
observations (:class:`avq.agents._warmup.RunningSpread` with ``log``) and, once they have them all, give the noise
and drifting dimensions an infinite scale (weight 0 in the distance); the log goes on while a drifting dimension
waits to be judged, which gives it back its scale if it matters.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "NOISE_R2",
    "RELEVANT_R2",
    "JUDGE_AFTER",
    "DRIFT_RELEVANT_R2",
    "noise_dims",
    "matters",
    "drift_dims",
    "drift_matters",
]

#: The share of a dimension's variance below which a linear prediction from the previous observation marks it as
#: noise (:func:`noise_dims`).
NOISE_R2 = 0.1
#: The share of what is left unexplained of the reward or of another dimension's next value that an unpredictable
#: dimension must explain, with the action, to be kept (:func:`matters`).
RELEVANT_R2 = 0.05
#: A drifting dimension (:func:`drift_dims`) is judged (:func:`drift_matters`) once this many observations are logged
#: (or the noise test's, if more).
JUDGE_AFTER = 30_000
#: The share of what is left unexplained of the reward or of another dimension's next value that a drifting
#: dimension must explain, judged later, to count in the metric again (:func:`drift_matters`).
DRIFT_RELEVANT_R2 = 0.1


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
    varied = _varies(variance, target)
    explained = 1.0 - residual / np.where(varied, variance, 1.0)
    noise = varied & (explained < NOISE_R2)
    if actions is not None and rewards is not None and noise.any():
        noise &= ~matters(obs, after, np.asarray(actions)[after], np.asarray(rewards, dtype=np.float64)[after], noise)
    return noise


def _varies(variance: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Whether each column's ``variance`` is more than rounding on the scale of its ``values``."""
    return variance > 1e-12 * np.maximum(1.0, np.abs(values).max(axis=0)) ** 2


def _one_hot(actions: np.ndarray) -> np.ndarray:
    """A column per action taken, 1 where it was."""
    _, which = np.unique(actions, return_inverse=True)
    return np.eye(int(which.max()) + 1)[which]


def _share(base: np.ndarray, target: np.ndarray, left: np.ndarray, own: np.ndarray, after: np.ndarray) -> float:
    """The largest share of what the fit on ``base`` leaves of a column of ``target`` (``left``; the first column
    the reward) that the columns ``own`` explain besides, or, of the reward, a dimension's value ``after`` the step
    (the reward may depend on the value the step led to: a leg that touches the ground)."""
    with_own = _left(np.column_stack([base, own]), target)
    with_own[0] = min(with_own[0], _left(np.column_stack([base, after]), target[:, :1])[0])
    return float(np.where(left > 1e-12, 1.0 - with_own / np.where(left > 1e-12, left, 1.0), 0.0).max())


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
    one_hot = _one_hot(actions)
    before = obs[after - 1]
    target = np.column_stack([rewards, obs[after][:, ~noise]])
    kept = np.zeros(len(noise), dtype=bool)
    base = np.column_stack([one_hot, np.delete(before, np.flatnonzero(noise), axis=1)])
    left = _left(base, target)
    for j in np.flatnonzero(noise):
        kept[j] = _share(base, target, left, one_hot * before[:, j : j + 1], obs[after, j]) >= RELEVANT_R2
    return kept


def _standard(x: np.ndarray) -> np.ndarray:
    """The columns of ``x`` less their means, over their standard deviations (a constant column: 0)."""
    sd = x.std(axis=0)
    return (x - x.mean(axis=0)) / np.where(sd > 0, sd, 1.0)


def _quadratic(z: np.ndarray, one_hot: np.ndarray) -> np.ndarray:
    """The columns of a quadratic fit on the standardized ``z`` and the action: one per action, ``z``, every
    product ``z_i z_k`` (``i <= k``), and ``z`` times each action but the first."""
    i, k = np.triu_indices(z.shape[1])
    return np.column_stack([one_hot, z, z[:, i] * z[:, k], (one_hot[:, 1:, None] * z[:, None, :]).reshape(len(z), -1)])


def _pairs(follows: np.ndarray, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The pairs within an episode whose action is known (``after``), and a column per action; None without."""
    after = np.flatnonzero(np.asarray(follows, dtype=bool)[1:]) + 1
    after = after[np.asarray(actions)[after] >= 0]
    if after.size == 0:
        return None
    return after, _one_hot(np.asarray(actions)[after])


def drift_dims(obs: np.ndarray, follows: np.ndarray, actions: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """Which dimensions of ``obs``, besides ``noise``, *drift*: their change from one step to the next is not
    predictable, where their next value is (a slow random walk, ``avq.envs.IrrelevantDims(kind="walk")``).

    The change of every dimension is fitted by least squares on :func:`_quadratic` columns of the previous
    observation and the action (a linear fit would not do: a link's cosine changes with its sine times its speed);
    a dimension whose change varies, and is not 0 in most steps, and of which the fit explains less than
    :data:`NOISE_R2`, adjusted for the number of columns (``1 - (1 - R^2) (pairs - 1) / (pairs - columns)``),
    drifts; the fit is made again without the noise and the dimensions found, until it finds no more (with 16
    dimensions the first fit has over 200 columns, and a walk may seem explained by chance). (A dimension that keeps its value in most steps changes in jumps: an event such as a leg's contact with
    the ground, which a quadratic fit does not predict but which follows the state.) Every dimension of
    CartPole-v1, MountainCar-v0 and Acrobot-v1 is explained 0.9 or more, LunarLander-v3's at least 0.3 but for its
    legs' contacts (events), an appended walk at most 0.08 (docs/results/dimensions.md, Walks). Nothing drifts
    without actions (a log without them), or with fewer than four pairs a column.
    """
    obs, noise = np.asarray(obs, dtype=np.float64), np.asarray(noise, dtype=bool)
    found = np.zeros(obs.shape[1], dtype=bool)
    pairs = _pairs(follows, actions)
    if pairs is None:
        return found
    after, one_hot = pairs
    change = obs[after] - obs[after - 1]
    variance = change.var(axis=0)
    varied = _varies(variance, obs[after])
    varied &= (change != 0).mean(axis=0) > 0.5  # (a dimension that mostly keeps its value changes in jumps: events)
    varied &= ~noise
    while True:  # (again without those found: fewer columns, less that a walk explains by chance)
        columns = _quadratic(_standard(obs[after - 1][:, ~found & ~noise]), one_hot)
        if after.size < 4 * columns.shape[1]:
            return found
        explained = 1.0 - _left(columns, change) / np.where(varied, variance, 1.0)
        adjusted = 1.0 - (1.0 - explained) * (after.size - 1) / (after.size - columns.shape[1])
        more = varied & ~found & (adjusted < NOISE_R2)
        if not more.any():
            return found
        found |= more


def drift_matters(
    obs: np.ndarray, follows: np.ndarray, actions: np.ndarray, rewards: np.ndarray, drift: np.ndarray
) -> np.ndarray:
    """Which of the dimensions ``drift`` explain at least :data:`DRIFT_RELEVANT_R2` of what a quadratic fit on the
    other dimensions and the action (:func:`_quadratic`) leaves unexplained of the reward or of the next value of
    another dimension, with columns of their own: their products with each action, with every other dimension
    and with themselves (a distance to a target that drifts), and for the reward their value after the step.

    Made on a long log only (:data:`JUDGE_AFTER` observations): a drifting dimension moves slowly, so over the few
    episodes of the first steps it correlates by chance with whatever else changes slowly (a walk explains up to 0.7
    of another dimension at 1,000 steps, 0.05 at 30,000, where a drifting target and a wind explain 0.4 or more and
    LunarLander's contacts 0.13; docs/results/dimensions.md, Walks)."""
    obs = np.asarray(obs, dtype=np.float64)
    drift = np.asarray(drift, dtype=bool)
    kept = np.zeros(len(drift), dtype=bool)
    pairs = _pairs(follows, actions)
    if pairs is None or not drift.any():
        return kept
    after, one_hot = pairs
    rest = _standard(obs[after - 1][:, ~drift])
    base = _quadratic(rest, one_hot)
    target = np.column_stack([np.asarray(rewards, dtype=np.float64)[after], obs[after][:, ~drift]])
    left = _left(base, target)
    for j in np.flatnonzero(drift):
        own = _standard(obs[after - 1, j : j + 1])
        columns = np.column_stack([one_hot * obs[after - 1, j : j + 1], own * rest, own**2])
        kept[j] = _share(base, target, left, columns, obs[after, j]) >= DRIFT_RELEVANT_R2
    return kept
