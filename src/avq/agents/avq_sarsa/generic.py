"""The generic path of AVQ Sarsa(λ): one compiled call per environment step, on two flat buffers.

Any Gymnasium environment is stepped from Python, with one compiled call per step
(:func:`generic_step`: the kernels' ``observe``, then at the end of an aggregate transition
``decide`` and ``learn``). The agent's arrays are views of two flat buffers, one float and one int,
so that a step hands Numba four arrays instead of a dozen (each array argument costs about 60 ns to
unbox). The int buffer begins with (cap, n, m); :func:`unpack` makes the views, :func:`packed_sizes`
says how long the buffers are. Float buffer: V (cap, n), Q (cap, m), E (cap, m), inv_scale (n), P, F,
a scratch observation (n) and a scratch profile (1, m). Int buffer: the dimensions, born (cap, 2 + m),
act (cap + 1), pc (cap + 1, 2), IP, S.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numba import njit
from numba.core.errors import TypingError

from avq._numba import borrowed, direct_call
from avq._random import DRAWS_PER_DECISION
from avq.agents._warmup import RunningSpread
from avq.agents.avq_sarsa.kernels import (
    ACTION,
    EP_STEPS,
    N_F,
    N_IP,
    N_P,
    N_S,
    NOT_FINITE,
    SIZE,
    Params,
    Step,
    begin_episode,
    decide,
    learn,
    observe,
)
from avq.agents.base import BaseAgent

__all__ = [
    "GenericPath",
    "generic_start",
    "generic_step",
    "packed_sizes",
    "python_views",
    "unpack",
    "N_DIMS",
    "ENDED",
    "NEED_DRAWS",
    "BAD_SHAPE",
    "NEED_ROOM",
]


N_DIMS = 3
#: Statuses of :func:`generic_step` (an action, >= 0, when the episode goes on).
ENDED, NEED_DRAWS, BAD_SHAPE, NEED_ROOM = -1, -3, -4, -5  # (NOT_FINITE is -2)


def _layout(cap: int, n: int, m: int) -> tuple[tuple, tuple]:
    """The shapes of the views, in buffer order: float ``V, Q, E, inv_scale, P, F, x, scr`` and int (after
    the dimensions) ``born, act, pc, IP, S`` (what :func:`unpack` cuts, compiled)."""
    return (
        ((cap, n), (cap, m), (cap, m), (n,), (N_P,), (N_F,), (n,), (1, m)),
        ((cap, 2 + m), (cap + 1,), (cap + 1, 2), (N_IP,), (N_S,)),
    )


def packed_sizes(cap: int, n: int, m: int) -> tuple[int, int]:
    """Lengths of the float and int buffers for ``cap`` cells of ``n`` dimensions and ``m`` actions."""
    f_shapes, i_shapes = _layout(cap, n, m)
    return (sum(math.prod(s) for s in f_shapes), N_DIMS + sum(math.prod(s) for s in i_shapes))


@njit(cache=True, inline="always")
def unpack(fb, ib):
    """The views ``(V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr)`` of the packed buffers
    (borrowed, see :func:`avq._numba.borrowed`: they must not outlive the call that made them)."""
    fb, ib = borrowed(fb), borrowed(ib)
    cap, n, m = ib[0], ib[1], ib[2]
    o = 0
    V = fb[o : o + cap * n].reshape((cap, n))
    o += cap * n
    Q = fb[o : o + cap * m].reshape((cap, m))
    o += cap * m
    E = fb[o : o + cap * m].reshape((cap, m))
    o += cap * m
    inv_scale = fb[o : o + n]
    o += n
    P = fb[o : o + N_P]
    o += N_P
    F = fb[o : o + N_F]
    o += N_F
    x = fb[o : o + n]
    o += n
    scr = fb[o : o + m].reshape((1, m))
    k = N_DIMS
    born = ib[k : k + cap * (2 + m)].reshape((cap, 2 + m))
    k += cap * (2 + m)
    act = ib[k : k + cap + 1]
    k += cap + 1
    pc = ib[k : k + 2 * (cap + 1)].reshape((cap + 1, 2))
    k += 2 * (cap + 1)
    IP = ib[k : k + N_IP]
    k += N_IP
    S = ib[k : k + N_S]
    return V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr


def python_views(fb: np.ndarray, ib: np.ndarray) -> tuple:
    """The same views as :func:`unpack`, made by NumPy (the agent's attributes)."""
    f_shapes, i_shapes = _layout(*(int(v) for v in ib[:N_DIMS]))
    f_views, i_views = _cut(fb, 0, f_shapes), _cut(ib, N_DIMS, i_shapes)
    V, Q, E, inv_scale, P, F, x, scr = f_views
    born, act, pc, IP, S = i_views
    return V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr


def _cut(buf: np.ndarray, start: int, shapes: tuple) -> list[np.ndarray]:
    """Consecutive views of ``buf`` from ``start``, one per shape."""
    out, o = [], start
    for shape in shapes:
        size = math.prod(shape)
        out.append(buf[o : o + size].reshape(shape))
        o += size
    return out


@njit(cache=True)
def generic_start(fb, ib, raw, cursor, obs) -> int:
    """Start an episode at ``obs`` (docs/explanation/paper.md#growing's first vector if the codebook is empty) and decide its
    first action; or ``NEED_ROOM`` / ``NEED_DRAWS`` / ``BAD_SHAPE`` / ``NOT_FINITE``, changing nothing."""
    raw, cursor = borrowed(raw), borrowed(cursor)
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr = unpack(fb, ib)
    if obs.shape[0] != x.shape[0]:
        return BAD_SHAPE
    if S[SIZE] + 1 > V.shape[0]:
        return NEED_ROOM
    if raw.shape[0] - cursor[0] < DRAWS_PER_DECISION:  # (a step takes at most one decision)
        return NEED_DRAWS
    for d in range(x.shape[0]):
        x[d] = obs[d]
        if not math.isfinite(x[d]):
            return NOT_FINITE
    cell = begin_episode(V, Q, E, born, act, S, F, Params(P, IP, inv_scale), x)
    S[ACTION] = decide((raw, cursor), Q, born, P, cell, scr)
    return S[ACTION]


@njit(cache=True)
def generic_step(fb, ib, raw, cursor, obs, r, collision, terminated, truncated) -> int:
    """One environment step of the generic path: :func:`observe`, then at the end of an aggregate
    transition the next decision and :func:`learn`. Returns the action to take next, ``ENDED``, or
    (changing nothing) ``NEED_ROOM``, ``NEED_DRAWS``, ``BAD_SHAPE``, ``NOT_FINITE``."""
    raw, cursor = borrowed(raw), borrowed(cursor)
    V, Q, E, born, act, pc, inv_scale, P, IP, S, F, x, scr = unpack(fb, ib)
    if obs.shape[0] != x.shape[0]:
        return BAD_SHAPE
    if S[SIZE] + 3 > V.shape[0]:  # a step appends at most three cells
        return NEED_ROOM
    if raw.shape[0] - cursor[0] < DRAWS_PER_DECISION:  # (a step takes at most one decision)
        return NEED_DRAWS
    for d in range(x.shape[0]):
        x[d] = obs[d]
    par, st = Params(P, IP, inv_scale), Step(x, float(r), collision, terminated, terminated or truncated)
    j = observe(V, Q, E, born, S, F, par, st)
    if j == NOT_FINITE:
        return NOT_FINITE
    if j < 0:
        return S[ACTION]
    a_next = S[ACTION]
    if not terminated:
        a_next = decide((raw, cursor), Q, born, P, j, scr)
    learn(V, Q, E, born, act, S, F, par, st, j, a_next)
    return ENDED if st.done else a_next


class GenericPath(BaseAgent):
    """AVQ Sarsa(λ)'s arrays as views of the two flat buffers, and the generic path's step loop over them
    (the agent, :class:`~avq.agents.AVQSarsa`, holds the parameters, the episode's ends and the fused loop)."""

    _fb: np.ndarray
    _ib: np.ndarray
    # Views of the two buffers (python_views), in the order of _VIEWS, and the agent's own attributes they use.
    _views: tuple
    _V: np.ndarray
    _Q: np.ndarray
    _E: np.ndarray
    _born: np.ndarray
    _act: np.ndarray
    _pc: np.ndarray
    _inv_scale: np.ndarray
    _P: np.ndarray
    _IP: np.ndarray
    _S: np.ndarray
    _F: np.ndarray
    _direct: tuple
    _spread: RunningSpread
    max_cells: int

    def _allocate(self, cap: int) -> None:
        """(Re)make the agent's arrays for ``cap`` cells, keeping what they hold.

        Every array is a view of two flat buffers (see :func:`avq.agents.avq_sarsa.kernels.unpack`), which the
        generic path hands to its one compiled call per step.
        """
        n, m = self._obs_shape()[0], self.n_actions
        fb_len, ib_len = packed_sizes(cap, n, m)
        fb, ib = np.zeros(fb_len), np.zeros(ib_len, dtype=np.int64)
        ib[:N_DIMS] = cap, n, m
        views = python_views(fb, ib)
        if getattr(self, "_fb", None) is not None:
            for new, old in zip(views, self._views):
                new[: len(old)] = old
        self._fb, self._ib, self._views = fb, ib, views
        for name, view in zip(self._VIEWS, views):
            setattr(self, name, view)

    def _ensure_capacity(self, extra: int) -> None:
        """Room for ``extra`` more cells (the kernels append in place and never reallocate): doubling, but
        never beyond ``max_cells`` and the few rows a step may ask for over it."""
        cap, size = self._V.shape[0], int(self._S[SIZE])
        if size + extra <= cap:
            return
        self._allocate(max(min(2 * cap, self.max_cells + 4), size + extra))

    _VIEWS = ("_V", "_Q", "_E", "_born", "_act", "_pc", "_inv_scale", "_P", "_IP", "_S", "_F")

    _transient: ClassVar[dict[str, Any]] = {"_direct": (None, None, None, None)}

    def __getstate__(self) -> dict[str, Any]:
        # The arrays are views of the two buffers: pickle the buffers and make the views again on loading.
        state = super().__getstate__()
        for name in self._VIEWS + ("_views",):
            state.pop(name, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if getattr(self, "_fb", None) is not None:
            views = python_views(self._fb, self._ib)
            self._views = views
            for name, view in zip(self._VIEWS, views):
                setattr(self, name, view)

    def _state(self) -> tuple[np.ndarray, ...]:
        return (
            self._V,
            self._Q,
            self._E,
            self._born,
            self._act,
            self._pc,
            self._inv_scale,
            self._P,
            self._IP,
            self._S,
            self._F,
        )

    def _as_reward(self, r: Any, step: int) -> float:
        try:
            return float(r)
        except (TypeError, ValueError):
            raise ValueError(
                f"reward {r!r} at step {step} of episode {self.num_episodes + 1} is not a number"
            ) from None

    def _as_obs(self, obs: Any, step: int) -> np.ndarray:
        x = np.asarray(obs, dtype=np.float64)
        if x.shape != self._V.shape[1:]:
            raise ValueError(f"observation at step {step} has shape {x.shape}; the space says {self._V.shape[1:]}")
        return x

    # -- the episode loop (docs/explanation/paper.md#acting, §5; the rules are in avq.agents.avq_sarsa.kernels) --------------
    def _compiled(self, kernel, obs: np.ndarray, step: int, r: Any, *args: Any) -> int:
        """``kernel(buffers, draws, obs, *args)``, growing the arrays or the draws when it asks for them;
        raises for an observation of the wrong shape, or an observation or reward that is not finite."""
        while True:
            draws = self._draws
            res = kernel(self._fb, self._ib, draws.raw, draws.cursor, obs, *args)
            if res == NEED_ROOM:
                self._ensure_capacity(3)
            elif res == NEED_DRAWS:
                draws.reserve()
            else:
                break
        if res == BAD_SHAPE:
            self._as_obs(obs, step)  # raises, naming the step
        if res == NOT_FINITE:
            self._refuse_non_finite(obs, r, step)
        return res

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        # One compiled call per step (generic_step). Once a step has gone through Numba's dispatcher,
        # later steps with arguments of the same types call the compiled function it chose directly
        # (avq._numba.direct_call), which halves the cost of a call; what the kernel cannot do at once (more room,
        # more draws, a bad observation) goes through _compiled, which then hands the step back here.
        step, kernel, S, draws = self.env.step, generic_step, self._S, self._draws
        fb, ib, raw, cursor = self._fb, self._ib, draws.raw, draws.cursor
        ended, ndarray = ENDED, np.ndarray
        # (the compiled function for the types of the last step that went through the dispatcher)
        direct, obs_dtype, obs_shape, r_type = self._direct
        count = None if self._spread.done else self._spread.add  # (during the warm-up, and its log)
        a = int(S[ACTION])
        n = 0
        while n < max_steps:
            obs, r, terminated, truncated, info = step(taken := a)
            n += 1
            collision = bool(info.get("collision", False))
            if (
                direct is not None
                and type(obs) is ndarray
                and obs.dtype is obs_dtype
                and obs.shape == obs_shape
                and obs.flags.c_contiguous
                and type(r) is r_type
            ):
                a = direct(fb, ib, raw, cursor, obs, r, collision, terminated, truncated)
            else:
                terminated, truncated = bool(terminated), bool(truncated)
                if type(obs) is not ndarray or obs.ndim != 1:
                    obs = self._as_obs(obs, int(S[EP_STEPS]) + 1)
                try:
                    a = kernel(fb, ib, raw, cursor, obs, r, collision, terminated, truncated)
                except TypingError:  # an observation or a reward of a type the kernel cannot read
                    obs = self._as_obs(obs, int(S[EP_STEPS]) + 1)
                    r = self._as_reward(r, int(S[EP_STEPS]) + 1)
                    a = NEED_DRAWS
                else:
                    direct = direct_call(kernel, (fb, ib, raw, cursor, obs, r, collision, terminated, truncated))
                    obs_dtype, obs_shape, r_type = obs.dtype, obs.shape, type(r)
                    self._direct = (direct, obs_dtype, obs_shape, r_type)
            if a < ended:
                a = self._compiled(kernel, obs, int(S[EP_STEPS]) + 1, r, r, collision, terminated, truncated)
                fb, ib, raw, S = self._fb, self._ib, draws.raw, self._S
            if count is not None and not count(obs, False, taken, float(r)):  # (an observation the kernel took: finite)
                count = None
            if a == ended:
                return n, True
        return n, False
