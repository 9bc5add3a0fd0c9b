"""Observation bounds and the metric's scale: the finite box an agent scales, bins or tiles (``obs_bounds``),
and for ``AVQSarsa``'s ``scale="auto"`` the scale of unbounded dimensions estimated from observations."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, overload

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._validate import check_bool, check_int
from avq.agents._noise import JUDGE_AFTER
from avq.agents._value_weights import MIN_CELLS, SETTLED_SHARE, slope_weights, value_slopes
from avq.agents._warmup import RunningSpread, load_scale_state, scale_state
from avq.agents.base import BaseAgent

__all__ = [
    "ScaledMetric",
    "check_discrete_actions",
    "check_table_spaces",
    "resolve_bounds",
    "resolve_scale",
    "auto_scale",
    "AUTO_SCALE_STDS",
    "per_dimension",
    "normalize_obs_bounds",
    "check_box_discrete",
]

#: ``scale="auto"`` takes this many standard deviations of the observations seen as the range of a
#: dimension without finite bounds: the width of ±2σ, which holds 95% of a normal distribution (and
#: about what ``high - low`` is to a uniform one, √12 ≈ 3.5σ).
AUTO_SCALE_STDS = 4.0


def _given_bounds(space: spaces.Space, obs_bounds: Sequence[Any] | None) -> tuple[np.ndarray, np.ndarray]:
    """The ``(low, high)`` per dimension of a 1-D ``Box`` space, overridden by ``obs_bounds``; maybe infinite."""
    low = np.asarray(space.low, dtype=np.float64).ravel().copy()  # type: ignore[attr-defined]
    high = np.asarray(space.high, dtype=np.float64).ravel().copy()  # type: ignore[attr-defined]
    n = low.shape[0]
    if obs_bounds is not None:
        entries = normalize_obs_bounds(obs_bounds)
        if len(entries) != n:
            raise ValueError(
                f"obs_bounds must have {n} entries (one per observation dimension), not {len(entries)}: "
                f"{obs_bounds!r}; give a (low, high) per dimension, None for those whose own bounds are fine"
            )
        for d, entry in enumerate(entries):
            if entry is not None:
                low[d], high[d] = entry
    return low, high


def resolve_bounds(space: spaces.Space, obs_bounds: Sequence[Any] | None) -> tuple[np.ndarray, np.ndarray]:
    """The finite ``(low, high)`` per dimension of a 1-D ``Box`` space, overridden by ``obs_bounds``.

    Args:
        space: A 1-D ``Box`` observation space.
        obs_bounds: None, or one entry per dimension: ``(low, high)`` or None to keep
            the space's bounds for that dimension.

    Raises:
        ValueError: ``obs_bounds`` is malformed, or a dimension ends up with an
            infinite or empty range (the message names the dimension).
    """
    low, high = _given_bounds(space, obs_bounds)
    n = low.shape[0]
    for d in range(n):
        if not (np.isfinite(low[d]) and np.isfinite(high[d])):
            raise ValueError(
                f"observation dimension {d} has bounds [{low[d]}, {high[d]}], so it cannot be scaled, "
                f"binned or tiled; pass obs_bounds= with a finite (low, high) for it, e.g. obs_bounds=[...] of "
                f"{n} entries, None for the dimensions whose bounds are fine"
            )
        if not high[d] > low[d]:
            raise ValueError(f"observation dimension {d} has bounds [{low[d]}, {high[d]}]; high must exceed low")
    return low, high


def auto_scale(
    space: spaces.Space, obs_bounds: Sequence[Any] | None, every: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """``scale="auto"`` (or with ``every``, ``scale="spread"``) before any observation: ``(scale, estimated)``.

    ``scale`` is ``high - low`` where the bounds (``obs_bounds`` or the space's) are finite, and 1 where
    they are not; ``estimated`` marks the latter, whose scale is then estimated from the observations
    (:class:`RunningSpread`). With ``every``, every dimension is estimated but those that ``obs_bounds``
    bounds: the space's own bounds are then only a start.

    Raises:
        ValueError: ``obs_bounds`` is malformed (:func:`normalize_obs_bounds`, and one entry per dimension);
            a space whose finite bounds have ``high <= low``.
    """
    low, high = _given_bounds(space, obs_bounds)
    finite = np.isfinite(low) & np.isfinite(high)
    scale = np.where(finite, high - low, 1.0)
    bad = np.flatnonzero(finite & ~(scale > 0))
    if bad.size:
        d = int(bad[0])
        raise ValueError(f"observation dimension {d} has bounds [{low[d]}, {high[d]}]; high must exceed low")
    estimated = ~finite
    if every:
        given = [entry is not None for entry in (normalize_obs_bounds(obs_bounds) or [None] * len(low))]
        estimated = ~np.array(given, dtype=bool)
    return scale, estimated


def scale_setting(
    space: spaces.Space, scale: Any, obs_bounds: Sequence[Any] | None, scale_factor: Any = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An agent's ``scale`` and ``scale_factor`` parameters as ``(scale, estimated, factor)``: ``"auto"`` and
    ``"spread"`` as :func:`auto_scale`, anything else as :func:`resolve_scale` (nothing estimated); then times
    ``factor``, ``scale_factor`` per dimension (:func:`per_dimension`), which the estimates of
    :func:`refresh_scale` keep when given it.

    Raises:
        ValueError: a string other than ``"auto"`` and ``"spread"``; what those two and :func:`per_dimension`
            raise.
    """
    n = space.shape[0]  # type: ignore[index]
    factor = per_dimension("scale_factor", scale_factor, n)
    if isinstance(scale, str):
        if scale not in ("auto", "spread"):
            raise ValueError(f"scale must be 'auto', 'spread', None, a number > 0 or one per dimension, not {scale!r}")
        s, estimated = auto_scale(space, obs_bounds, every=scale == "spread")
    else:
        s, estimated = resolve_scale(space, scale, obs_bounds), np.zeros(n, dtype=bool)
    return s * factor, estimated, factor


def refresh_scale(
    scale: np.ndarray,
    inv_scale: np.ndarray,
    estimated: np.ndarray,
    spread: RunningSpread,
    factor: np.ndarray | float = 1.0,
) -> bool:
    """``scale="auto"`` (or ``"spread"``) brought up to date in place: each estimated dimension becomes
    ``AUTO_SCALE_STDS`` standard deviations of the observations counted (where that is > 0) times ``factor``,
    and ``inv_scale`` its inverse. Returns whether anything changed (the caller's cells may then have moved)."""
    std = AUTO_SCALE_STDS * spread.std() * factor
    new = np.where(estimated & (std > 0), std, scale)
    if np.array_equal(new, scale):
        return False
    scale[:] = new
    inv_scale[:] = 1.0 / new
    return True


def resolve_scale(space: spaces.Space, scale: Any, obs_bounds: Sequence[Any] | None) -> np.ndarray:
    """The per-dimension scale of a codebook's metric: ``scale`` (a number or one per dimension), or with
    ``scale=None`` the ``high - low`` of the observation bounds (``obs_bounds`` or the space's).

    Raises:
        ValueError: both ``scale`` and ``obs_bounds`` given; a scale that is not finite and > 0; bounds
            that are not finite (see :func:`resolve_bounds`).
    """
    n = space.shape[0]  # type: ignore[index]
    if scale is not None and obs_bounds is not None:
        raise ValueError(
            "give scale or obs_bounds, not both (avq-paper sets scale=1, the paper's plain distance: "
            "pass scale=None with obs_bounds to scale by bounds instead)"
        )
    if scale is None:
        low, high = resolve_bounds(space, obs_bounds)
        return high - low
    return per_dimension("scale", scale, n)


def per_dimension(name: str, value: Any, n: int) -> np.ndarray:
    """``value``, a number or one per dimension, as ``(n,)`` floats, each finite and > 0.

    Raises:
        ValueError: naming ``name``: neither a number nor ``n`` numbers, or one that is not finite and > 0.
    """
    try:
        s = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy()
    except (ValueError, TypeError):
        raise ValueError(
            f"{name} must be a number or {n} numbers (one per observation dimension), not {value!r}"
        ) from None
    bad = np.flatnonzero(~(np.isfinite(s) & (s > 0)))
    if bad.size:
        raise ValueError(f"{name} must be finite and > 0; dimension {int(bad[0])} has {s[bad[0]]}")
    return s


@overload
def normalize_obs_bounds(obs_bounds: None) -> None: ...
@overload
def normalize_obs_bounds(obs_bounds: Sequence[Any]) -> list[list[float] | None]: ...
def normalize_obs_bounds(obs_bounds: Sequence[Any] | None) -> list[list[float] | None] | None:
    """``obs_bounds`` as JSON-able lists of floats (so that it survives saving), checked for form.

    Raises:
        ValueError: an entry is neither None nor a pair of numbers with ``low < high``.
    """
    if obs_bounds is None:
        return None
    if isinstance(obs_bounds, (str, bytes)) or not hasattr(obs_bounds, "__len__"):
        raise ValueError(f"obs_bounds must be None or a sequence of (low, high) pairs, not {obs_bounds!r}")
    out: list[list[float] | None] = []
    for d, entry in enumerate(obs_bounds):
        if entry is None:
            out.append(None)
            continue
        try:
            lo, hi = (float(v) for v in entry)
        except (TypeError, ValueError):
            raise ValueError(f"obs_bounds[{d}] must be a (low, high) pair of numbers or None, not {entry!r}") from None
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ValueError(
                f"obs_bounds[{d}] is {entry!r}, which is not finite; give finite numbers (low, high), "
                "or None to keep the space's bounds for that dimension"
            )
        if not hi > lo:
            raise ValueError(
                f"obs_bounds[{d}] is {entry!r}, whose low is not below its high; give (low, high) with low < high"
            )
        out.append([lo, hi])
    return out


def check_box_discrete(agent: str, obs_space: spaces.Space, act_space: spaces.Space, why: str) -> None:
    """Require a 1-D ``Box`` observation space and ``Discrete`` actions.

    A ``Discrete`` observation space gets a message pointing to the tabular agent;
    ``why`` says in a few words why this agent has no use for one.
    """
    if isinstance(obs_space, spaces.Discrete):
        raise ValueError(
            f"{agent} needs a Box observation space, but this environment's is Discrete: "
            f"{why}; use the 'tabular' agent (avq.TabularSarsa)"
        )
    if not isinstance(obs_space, spaces.Box) or len(obs_space.shape) != 1:
        raise ValueError(f"{agent} needs a 1-D Box observation space, not {obs_space}")
    check_discrete_actions(agent, act_space)


def check_discrete_actions(agent: str, act_space: spaces.Space) -> None:
    """Require ``Discrete`` actions numbered from 0 (the agents act with ``0 .. n - 1``); a ``Box`` action space
    gets a message pointing to the agents for it, a ``start`` other than 0 one that says how to number them from
    0."""
    if not isinstance(act_space, spaces.Discrete):
        raise ValueError(
            f"{agent} needs a Discrete action space, not {act_space}"
            + (
                "; for continuous actions use the agent 'avq-actions' (or 'uniform-actions')"
                if isinstance(act_space, spaces.Box)
                else ""
            )
        )
    start, n = int(act_space.start), int(act_space.n)
    if start != 0:
        raise ValueError(
            f"{agent} needs Discrete actions numbered from 0, not {act_space} (start={start}); number them from 0 "
            f"with gymnasium.wrappers.TransformAction(env, lambda a: a + {start}, gymnasium.spaces.Discrete({n}))"
        )


def check_table_spaces(agent: str, obs_space: spaces.Space, act_space: spaces.Space) -> bool:
    """Require ``Discrete`` actions and a ``Discrete`` or ``Box`` observation space (a table's keys); True
    when the observations are ``Discrete``."""
    check_discrete_actions(agent, act_space)
    if not isinstance(obs_space, (spaces.Discrete, spaces.Box)):
        raise ValueError(f"{agent} needs a Discrete or Box observation space, not {obs_space}")
    return isinstance(obs_space, spaces.Discrete)


class ScaledMetric(BaseAgent):
    """The base of the agents whose cells are vectors in observation units (``AVQSarsa``, ``PlanningAVQ``):
    their scaled metric, its parameters ``scale``, ``scale_factor`` and ``obs_bounds`` resolved once
    (:func:`scale_setting`), the count of observations from which ``scale="auto"`` estimates it, and the
    spaces they quantize (a 1-D ``Box`` of observations, ``Discrete`` actions)."""

    scale: Any
    scale_warmup: int
    obs_bounds: list[list[float] | None] | None

    def __init__(
        self,
        env: gym.Env | str,
        seed: int | None,
        scale: Any,
        scale_warmup: int,
        scale_factor: float | Sequence[float],
        obs_bounds: Sequence[Any] | None,
        ignore_noise: bool = True,
        reweight_when_full: bool = False,
    ) -> None:
        """Store and check the metric's parameters (``scale`` as given), make the environment
        (``BaseAgent``), then resolve the scale in force and ``scale_factor`` as a number or a list. A
        subclass checks its own parameters first; one that takes ``reweight_when_full`` gives the values
        (:meth:`_settled_values`)."""
        self.scale = scale
        self.reweight_when_full = check_bool("reweight_when_full", reweight_when_full)
        self.scale_warmup = check_int("scale_warmup", scale_warmup, 2)
        self.obs_bounds = normalize_obs_bounds(obs_bounds)
        self.ignore_noise = check_bool("ignore_noise", ignore_noise)
        super().__init__(env, seed)
        #: The dimensions whose scale is estimated from the observations (scale="auto" without finite bounds).
        self._scale, self._estimated, self._factor = scale_setting(
            self.env.observation_space, self.scale, self.obs_bounds, scale_factor
        )
        self.scale_factor = float(self._factor[0]) if np.ndim(scale_factor) == 0 else self._factor.tolist()
        #: ignore_noise with scale "auto" or "spread": the noise test (avq.agents._noise) is to be made once the
        #: first scale_warmup observations are counted; _noise_tested once it is.
        self._tests_noise = self.ignore_noise and isinstance(self.scale, str)
        self._noise_tested = False
        #: The dimensions the noise test found drifting, left out until the log is long enough to judge them
        #: (avq.agents._noise.drift_matters), and the scale each had then.
        self._drifting = np.zeros(len(self._scale), dtype=bool)
        self._held = np.zeros(len(self._scale))
        #: The weights learned from the values' slopes (reweight_when_full; avq.agents._value_weights), 1 until then.
        self._weights = np.ones(len(self._scale))
        self._weighted = False

    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        check_box_discrete(type(self).__name__, obs_space, act_space, "there is nothing to quantize")

    @property
    def scale_(self) -> np.ndarray:
        """The metric's scale in force, one number per dimension: ``scale``, or the ``high - low`` of the
        observation bounds (``obs_bounds`` or the space's), or with ``scale="auto"`` where those are not
        finite the estimate from the observations so far; ``inf`` for a dimension found to be noise or to drift
        (``ignore_noise``), which the distance then ignores."""
        return self._scale.copy()

    @property
    def _learns_metric(self) -> bool:
        """Whether the metric may still change at the end of an episode (``scale="auto"``'s estimates, the noise
        test, drifting dimensions not yet judged, or ``reweight_when_full`` not yet done): the fused loops, which count
        no observations and see no values, are then not used."""
        waits = (self._tests_noise and not self._noise_tested) or (self.reweight_when_full and not self._weighted)
        return bool(self._estimated.any() or self._drifting.any()) or waits

    def _new_spread(self) -> RunningSpread:
        """The observations to count for ``scale="auto"`` and the noise test (none when neither needs them)."""
        counted = self._estimated.any() or self._tests_noise
        return RunningSpread(len(self._scale), self.scale_warmup if counted else 0, log=self._tests_noise)

    def _refresh_metric(self, spread: RunningSpread, inv_scale: np.ndarray, full: bool = False) -> bool:
        """At the end of an episode: ``scale="auto"``'s estimates brought up to date (:func:`refresh_scale`), and
        once ``spread`` counted its ``scale_warmup`` observations, the noise test made (once): a dimension found
        to be noise, or to drift, gets an infinite scale and ``inv_scale`` 0; once the log then holds
        ``JUDGE_AFTER`` observations, a drifting dimension that matters gets its scale back (once); with
        ``reweight_when_full``, once the caller's codebook is ``full``, the metric weighted by the values' slopes
        (:meth:`_reweight`). Returns whether the metric changed."""
        noise = np.isinf(self._scale)
        changed = bool(self._estimated.any()) and refresh_scale(
            self._scale, inv_scale, self._estimated & ~noise, spread, self._factor
        )
        if spread.obs is not None and not self._noise_tested and spread.full:
            self._noise_tested = True
            found = spread.noise()
            drift = spread.drift(found)
            if drift.any():  # (left out now, judged once the log holds JUDGE_AFTER observations)
                self._drifting, self._held = drift, np.where(drift, self._scale, 0.0)
                spread.extend_log(max(JUDGE_AFTER, spread.limit))
            if (found | drift).any():
                self._scale[found | drift], inv_scale[found | drift] = np.inf, 0.0
                changed = True
        elif self._drifting.any() and spread.log_full:
            back = spread.drift_matters(self._drifting)
            self._scale[back], inv_scale[back] = self._held[back], 1.0 / self._held[back]
            self._drifting[:] = False
            changed = changed or bool(back.any())
        due = self.reweight_when_full and full and not self._weighted
        return (due and self._reweight(inv_scale)) or changed

    def _settled_values(self) -> tuple[np.ndarray, np.ndarray, int]:
        """The vectors (observation units, ``(p, n)``) and planned values (``(p,)``) of the cells whose every
        decision is known, and the number of all the cells: what ``reweight_when_full`` fits the slopes to. Given by
        the agents that take it."""
        raise NotImplementedError(f"{type(self).__name__} does not learn its metric's weights from its values")

    def _reweight(self, inv_scale: np.ndarray) -> bool:
        """``reweight_when_full``: once :data:`~avq.agents._value_weights.MIN_CELLS` cells are settled, and at least
        :data:`~avq.agents._value_weights.SETTLED_SHARE` of all the cells, weight each dimension of the metric (those
        it counts) by the slope of their values along it (:func:`~avq.agents._value_weights.slope_weights`): its
        scale, and the factor that ``scale="auto"``'s estimates keep, divided by the weight. Returns whether it did
        (else it is tried again at the next call)."""
        vectors, values, cells = self._settled_values()
        live = inv_scale > 0
        if len(values) < max(MIN_CELLS, SETTLED_SHARE * cells) or not live.any():
            return False
        self._weights[live] = slope_weights(value_slopes(vectors[:, live] * inv_scale[live], values))
        self._weighted = True
        self._factor = self._factor / self._weights
        self._scale /= self._weights
        inv_scale[:] = 1.0 / self._scale
        return True

    def _metric_state(self, spread: RunningSpread) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """What a saved agent keeps of its metric (:func:`scale_state`, and whether the noise test was made)."""
        noise = np.isinf(self._scale)
        meta, arrays = scale_state(np.where(noise, 1.0, self._scale), spread)  # (a model file holds finite numbers)
        arrays["noise_dims"] = noise.astype(np.int8)
        arrays["drift_dims"], arrays["drift_scale"] = self._drifting.astype(np.int8), self._held.copy()
        if self._weighted:  # (reweight_when_full: the weights in force)
            arrays["metric_weights"] = self._weights.copy()
        return dict(meta, noise_tested=self._noise_tested), arrays

    def _load_metric_state(self, meta: dict[str, Any], arrays: dict[str, np.ndarray], spread: RunningSpread) -> None:
        """Restore what :meth:`_metric_state` saved (:func:`load_scale_state`)."""
        noise = arrays.get("noise_dims", np.zeros(len(self._scale), dtype=np.int8))
        if noise.shape != self._scale.shape or (noise.any() and not self._tests_noise):
            raise ValueError(f"array noise_dims {noise.tolist()} does not fit the parameters' scale and ignore_noise")
        weights = arrays.get("metric_weights", np.ones(len(self._scale)))
        if weights.shape != self._scale.shape or not (weights > 0).all():
            raise ValueError(f"array metric_weights {weights.tolist()} must hold one number > 0 per dimension")
        self._weights, self._weighted = weights.astype(np.float64), "metric_weights" in arrays
        self._factor = self._factor / self._weights
        self._scale /= self._weights
        load_scale_state(meta, arrays, self._scale, self._estimated | (noise > 0), spread)
        self._scale[noise > 0] = np.inf
        self._noise_tested = bool(meta.get("noise_tested", False))
        drift = arrays.get("drift_dims", np.zeros(len(self._scale), dtype=np.int8))
        held = arrays.get("drift_scale", np.zeros(len(self._scale)))
        if drift.shape != self._scale.shape or held.shape != self._scale.shape or ((drift > 0) & ~(noise > 0)).any():
            raise ValueError(f"arrays drift_dims {drift.tolist()} and drift_scale do not fit the noise dimensions")
        self._drifting, self._held = drift > 0, held.astype(np.float64)
