"""A learned model of (state, action) -> successor, and prioritized sweeping over it.

One implementation serves every model-based agent: ``tabular-ps`` (a state is a distinct
observation, a transition one environment step) and ``avq-plan`` (a state is a cell of the
codebook, a transition one aggregate transition, ``k`` steps long; docs:
explanation/paper.md, Acting). The model keeps, for each pair ``(s, a)``, the number of transitions
``n(s, a)``, the sum of their returns, and for each successor ``s'`` seen the sum of the discounts
``gamma ** k`` of the transitions that reached it (a terminal successor is ``-1``, worth 0). So the model is right for stochastic tasks and for
transitions of any duration (an SMDP step):

    Q(s, a) = ( sum R + sum_{s'} (sum gamma ** k to s') * V(s') ) / n(s, a)      V(s) = max_a Q(s, a)

**Decisions that go on** (``avq-plan``'s merged cells): a transition that ended only because the cell
changed, and whose two ends now lie in one cell, is recorded with the successor :data:`CONT`: the decision
would have gone on, so its value is the pair's own, ``Q(s, a)``, not ``V(s)``. Solved for ``Q(s, a)``:

    Q(s, a) = ( sum R + sum_{s' != CONT} (sum gamma ** k to s') * V(s') ) / ( n(s, a) - sum gamma ** k to CONT )

which is the cell's own loop, ``(I - P)^-1``, for any number of merges. ``cint`` counts those transitions:
a pair is known once ``n - cint`` (transitions that left the cell) reaches ``known``.

**Optimism** (R-max): a pair tried fewer than ``known`` times leads to a fictitious absorbing
state worth ``v_opt``: ``Q(s, a) = v_opt``. A new state has every action unknown. **A floor**
``v_min`` bounds every known value from below, so that a model that loops for ever at a loss (a cell whose
every action comes back to it, with ``gamma = 1``) converges instead of falling without end; a ceiling
``v_max`` (none unless set: :meth:`Model.set_optimism`) bounds it from above against loops at a gain.

**Prioritized sweeping** (Moore & Atkeson 1993): after a transition is recorded, its state is
backed up at once; whenever a backup changes ``V(s)`` by ``dv``, each predecessor pair
``(q, b)`` of ``s`` is queued with priority ``dv * (discount mass from (q, b) to s) / n(q, b)``
if that exceeds ``tol``. Then at most ``budget`` queued states, highest priority first, are
backed up (every action of the state). What the budget leaves in the queue stays for the next
call, so values converge over the following steps; the queue is empty when they have (to
``tol``). The model follows transitions that are removed as well as added (``sign = -1``),
which is how ``avq-plan`` re-maps its remembered transitions when its cells change.

Arrays (capacity ``S`` states, ``m`` actions, ``E`` edges), held by :class:`Model`, taken by the compiled
functions as one record, :class:`ModelArrays`: per pair ``cnt``, ``cint``, ``rsum`` and ``head`` (the first edge
of its successor list); ``Q``, ``V``; edges ``e_to``, ``e_next``, ``e_n``, ``e_disc`` (discount mass), ``e_r``;
predecessors, one entry per edge into a state: ``p_head``, ``p_sa`` (``q * m + b``), ``p_edge``, ``p_next``;
the queue ``heap``, ``hpos``, ``prio`` (:mod:`avq.agents.plan.queue`); counters ``C``; parameters ``MP``.
"""

from __future__ import annotations

from enum import auto
from typing import NamedTuple

import numpy as np
from numba import njit

from avq._numba import Compiled, borrowed
from avq.agents._params import ParamIndex, pack_params
from avq.agents.plan.queue import HEAP_N, pop, push

__all__ = [
    "CONT", "Model", "ModelArrays", "ModelParam", "PLANNING_PARAMS", "backup_into", "borrowed_model", "clear", "known"
]  # fmt: skip

#: The options of every agent that learns this model and plans over it (``tabular-ps``, ``avq-plan``).
PLANNING_PARAMS = ("v_opt", "v_min", "known_after", "n_backups", "tol")

# C: int counters (and ``known``, the one int parameter, kept with them as saved model files hold it there);
# C[HEAP_N] (3) is the queue's length (avq.agents.plan.queue)
N_STATES, N_EDGES, N_PREDS, _, BACKUPS, KNOWN = range(6)
N_C = 6


class ModelParam(ParamIndex):
    """``MP``: the model's float parameters, read by :func:`backup` and :func:`propagate`."""

    V_OPT = auto()  # value of a pair not yet known (optimism)
    V_MIN = auto()  # floor of every known value
    TOL = auto()  # smallest change of a value that is propagated
    V_MAX = auto()  # ceiling of every known value (NO_CEILING: none)


FIRST = 1e300  # the priority that makes a state's backup come first
NO_CEILING = float(np.finfo(np.float64).max)  # v_max when none is set (finite: model files hold finite numbers)
#: The successor of a transition that goes on in its own cell (its value is the pair's own); -1 is terminal.
CONT = -2


class ModelArrays(NamedTuple):
    """The model's arrays: the record the compiled functions take (as ``m``), and the order of a model file.

    A function takes the arrays it uses into local names once (``cnt = m.cnt``), not in its loops: each
    ``m.cnt`` is a new reference to count (borrowed, :class:`avq._numba.BorrowedArray`: none).

    Beware: in functions inlined at Numba's IR level (``inline="always"``) with a record argument, Numba 0.68
    silently dropped some writes to the record's arrays: the predecessor lists of :func:`record` (when
    written through local names inside the agents' kernels, and when written as ``m.p_sa[k] = ...`` inside a
    fused loop that builds ``m`` itself), and ``tabular-ps``'s table in its fused loop. Those writes are
    made in functions that are not inlined and take the arrays themselves (:func:`_add_predecessor`,
    ``fused._ps_row``'s arrays taken by its caller); the bit-for-bit comparison with the previous release
    caught it. (Numba's on-disk cache does not notice a change to an inlined function of another module:
    clear ``__pycache__`` when comparing.)
    """

    cnt: np.ndarray
    cint: np.ndarray
    rsum: np.ndarray
    head: np.ndarray
    Q: np.ndarray
    V: np.ndarray
    e_to: np.ndarray
    e_next: np.ndarray
    e_n: np.ndarray
    e_disc: np.ndarray
    e_r: np.ndarray
    p_head: np.ndarray
    p_sa: np.ndarray
    p_edge: np.ndarray
    p_next: np.ndarray
    heap: np.ndarray
    hpos: np.ndarray
    prio: np.ndarray
    C: np.ndarray
    MP: np.ndarray


@njit(cache=True, inline="always")
def borrowed_model(m: ModelArrays) -> ModelArrays:
    """``m`` with its arrays as borrowed views (:func:`avq._numba.borrowed`), for a fused loop's own use."""
    return ModelArrays(
        borrowed(m.cnt),
        borrowed(m.cint),
        borrowed(m.rsum),
        borrowed(m.head),
        borrowed(m.Q),
        borrowed(m.V),
        borrowed(m.e_to),
        borrowed(m.e_next),
        borrowed(m.e_n),
        borrowed(m.e_disc),
        borrowed(m.e_r),
        borrowed(m.p_head),
        borrowed(m.p_sa),
        borrowed(m.p_edge),
        borrowed(m.p_next),
        borrowed(m.heap),
        borrowed(m.hpos),
        borrowed(m.prio),
        borrowed(m.C),
        borrowed(m.MP),
    )


def _empty(states: int, m: int, edges: int, v_opt: float) -> ModelArrays:
    return ModelArrays(
        cnt=np.zeros((states, m), dtype=np.int64),
        cint=np.zeros((states, m), dtype=np.int64),
        rsum=np.zeros((states, m)),
        head=np.full((states, m), -1, dtype=np.int64),
        Q=np.full((states, m), v_opt),
        V=np.full(states, v_opt),
        e_to=np.zeros(edges, dtype=np.int64),
        e_next=np.zeros(edges, dtype=np.int64),
        e_n=np.zeros(edges, dtype=np.int64),
        e_disc=np.zeros(edges),
        e_r=np.zeros(edges),
        p_head=np.full(states, -1, dtype=np.int64),
        p_sa=np.zeros(edges, dtype=np.int64),
        p_edge=np.zeros(edges, dtype=np.int64),
        p_next=np.zeros(edges, dtype=np.int64),
        heap=np.zeros(states, dtype=np.int64),
        hpos=np.full(states, -1, dtype=np.int64),
        prio=np.zeros(states),
        C=np.zeros(N_C, dtype=np.int64),
        MP=np.zeros(len(ModelParam)),
    )


class Model:
    """The learned model and its planner's state, growing as states and successors appear.

    Args:
        m: Number of actions.
        v_opt, v_min: Value of a pair tried fewer than ``known`` times (optimism); floor of every known value.
        known: Transitions after which a pair's own statistics replace ``v_opt``.
        tol: Smallest change of a value that is propagated.
    """

    def __init__(self, m: int, v_opt: float, v_min: float, known: int, tol: float, states: int = 64) -> None:
        self.m = m
        self.a = _empty(states, m, 4 * states, v_opt)
        pack_params(ModelParam, {"v_opt": v_opt, "v_min": v_min, "tol": tol, "v_max": NO_CEILING}, out=self.a.MP)
        self.a.C[KNOWN] = known
        self._add_state, self._sweep = Compiled(add_state), Compiled(sweep)

    @property
    def n_states(self) -> int:
        return int(self.a.C[N_STATES])

    @property
    def backups(self) -> int:
        """Backups done so far (every one, the immediate backup of a recorded transition's state included)."""
        return int(self.a.C[BACKUPS])

    @property
    def queued(self) -> int:
        """States waiting in the queue: 0 when the values have converged (to ``tol``)."""
        return int(self.a.C[HEAP_N])

    def reserve(self, states: int = 0, edges: int = 0) -> None:
        """Room for ``states`` more states and ``edges`` more edges (doubling)."""
        a = self.a
        need_s, need_e = int(a.C[N_STATES]) + states, int(a.C[N_EDGES]) + edges
        cap_s, cap_e = a.cnt.shape[0], a.e_to.shape[0]
        if need_s <= cap_s and need_e <= cap_e:
            return
        grown = lambda need, cap: cap if need <= cap else max(need, 2 * cap)  # noqa: E731
        new = _empty(grown(need_s, cap_s), self.m, grown(need_e, cap_e), float(a.MP[ModelParam.V_OPT]))
        for old, arr in zip(a, new):
            arr[: len(old)] = old
        self.a = new

    def add_state(self) -> int:
        """A new state, every action unknown (worth ``v_opt``)."""
        self.reserve(states=1)
        return self._add_state(self.a)

    def set_optimism(self, v_opt: float, v_max: float = NO_CEILING) -> None:
        """Make untried pairs worth ``v_opt`` and no known value more than ``v_max`` from now on: every state is
        backed up once and queued, so that a change reaches its predecessors over the next sweeps."""
        a, v_max = self.a, min(v_max, NO_CEILING)
        if v_opt == a.MP[ModelParam.V_OPT] and v_max == a.MP[ModelParam.V_MAX]:
            return
        a.MP[ModelParam.V_OPT], a.MP[ModelParam.V_MAX] = v_opt, v_max
        for s in range(self.n_states):
            self.queue(s, FIRST)
        self.sweep(self.n_states)

    def queue(self, s: int, priority: float) -> None:
        """Queue state ``s`` for a backup with ``priority`` (or raise its priority to it)."""
        push(self.a.heap, self.a.hpos, self.a.prio, self.a.C, s, priority)

    def sweep(self, budget: int) -> int:
        """Back up at most ``budget`` queued states, highest priority first; return how many."""
        return self._sweep(self.a, int(budget))

    def state_dict(self) -> dict[str, np.ndarray]:
        """The arrays in use, for a model file."""
        a, s, e = self.a, self.n_states, int(self.a.C[N_EDGES])
        return {
            "m_" + name: arr[: {"S": s, "E": e, "-": len(arr)}[_DIM[name]]].copy()
            for name, arr in zip(ModelArrays._fields, a)
        }

    def load_state_dict(self, arrays: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`state_dict` gave (shapes are checked by the caller's file format)."""
        C = arrays["m_C"]
        self.reserve(states=int(C[N_STATES]), edges=int(C[N_EDGES]))
        for name, arr in zip(ModelArrays._fields, self.a):
            if name == "cint" and "m_cint" not in arrays:
                continue  # (a file from before merging: no transition goes on, cint is 0)
            src = arrays["m_" + name]
            if src.shape[1:] != arr.shape[1:] or len(src) > len(arr):
                raise ValueError(f"model array {name} has shape {src.shape}, which does not fit {arr.shape}")
            arr[: len(src)] = src


#: Which capacity each array's first dimension follows: states ("S"), edges ("E"), or its own length ("-").
_DIM = dict.fromkeys(("cnt", "cint", "rsum", "head", "Q", "V", "p_head", "heap", "hpos", "prio"), "S")
_DIM.update(dict.fromkeys(("e_to", "e_next", "e_n", "e_disc", "e_r", "p_sa", "p_edge", "p_next"), "E"), C="-", MP="-")


@njit(cache=True)
def add_state(m: ModelArrays) -> int:
    """A new state, every action unknown (worth ``v_opt``); the caller makes room for it."""
    cnt, rsum, head, Q, V, p_head, hpos, C = m.cnt, m.rsum, m.head, m.Q, m.V, m.p_head, m.hpos, m.C
    s = C[N_STATES]
    for a in range(Q.shape[1]):
        cnt[s, a] = 0
        m.cint[s, a] = 0
        rsum[s, a] = 0.0
        head[s, a] = -1
        Q[s, a] = m.MP[ModelParam.V_OPT]
    V[s] = m.MP[ModelParam.V_OPT]
    p_head[s] = -1
    hpos[s] = -1
    C[N_STATES] = s + 1
    return s


@njit(cache=True)
def clear(m: ModelArrays) -> None:
    """Forget every transition (the states stay, with their values): the model is then rebuilt by recording
    transitions again. Every state is queued first."""
    m.cnt[:] = 0
    m.cint[:] = 0
    m.rsum[:] = 0.0
    m.head[:] = -1
    m.p_head[:] = -1
    m.hpos[:] = -1
    m.C[N_EDGES] = 0
    m.C[N_PREDS] = 0
    m.C[HEAP_N] = 0
    for s in range(m.C[N_STATES]):
        push(m.heap, m.hpos, m.prio, m.C, s, FIRST)


@njit(cache=True, inline="always")
def backup(m: ModelArrays, s: int) -> float:
    """Recompute ``Q[s]`` and ``V[s]`` from the model; return ``|change of V[s]|``."""
    m.C[BACKUPS] += 1
    return backup_into(m, s, m.Q, m.V, m.MP[ModelParam.V_OPT], m.MP[ModelParam.V_MAX])


@njit(cache=True)  # (not inlined: inlined, tabular-ps's fused loop lost writes; see ModelArrays)
def backup_into(m: ModelArrays, s: int, Q, V, v_untried: float, v_max: float) -> float:
    """:func:`backup` into the values ``Q``, ``V`` (the model's, or a plan of its own), a pair not yet known
    worth ``v_untried``, no known value above ``v_max`` (not counted in ``backups``); return
    ``|change of V[s]|``."""
    cnt, cint, rsum, head, e_to, e_next, e_disc, C, MP = (
        m.cnt, m.cint, m.rsum, m.head, m.e_to, m.e_next, m.e_disc, m.C, m.MP
    )  # (taken once: see ModelArrays)  # fmt: skip
    best = -np.inf
    for a in range(Q.shape[1]):
        n = cnt[s, a]
        if n - cint[s, a] < C[KNOWN]:
            q = v_untried
        else:
            total = rsum[s, a]
            stays = 0.0
            e = head[s, a]
            while e >= 0:
                t = e_to[e]
                if t >= 0:
                    total += e_disc[e] * V[t]
                elif t == CONT:
                    stays += e_disc[e]
                e = e_next[e]
            q = total / (n - stays)
            q = min(max(q, MP[ModelParam.V_MIN]), v_max)
        Q[s, a] = q
        if q > best:
            best = q
    change = abs(best - V[s])
    V[s] = best
    return change


@njit(cache=True, inline="always")
def propagate(m: ModelArrays, s: int, dv: float) -> None:
    """Queue each known predecessor pair's state of ``s`` by how much ``V[s]``'s change ``dv`` moves it."""
    cnt, e_n, e_disc, p_head, p_sa, p_edge, p_next = m.cnt, m.e_n, m.e_disc, m.p_head, m.p_sa, m.p_edge, m.p_next
    heap, hpos, prio, C, tol = m.heap, m.hpos, m.prio, m.C, m.MP[ModelParam.TOL]  # (taken once: see ModelArrays)
    n_actions = cnt.shape[1]
    k = p_head[s]
    while k >= 0:
        q = p_sa[k] // n_actions
        b = p_sa[k] - q * n_actions
        e = p_edge[k]
        n = cnt[q, b]
        if n - m.cint[q, b] >= C[KNOWN] and e_n[e] > 0:
            p = dv * e_disc[e] / n
            if p > tol:
                push(heap, hpos, prio, C, q, p)
        k = p_next[k]


@njit(cache=True, inline="always")
def sweep(m: ModelArrays, budget: int) -> int:
    """Back up at most ``budget`` queued states, highest priority first; return how many."""
    heap, hpos, prio, C = m.heap, m.hpos, m.prio, m.C  # (written: see the note on ModelArrays)
    done = 0
    while C[HEAP_N] > 0 and done < budget:
        s = pop(heap, hpos, prio, C)
        dv = backup(m, s)
        done += 1
        if dv > m.MP[ModelParam.TOL]:
            propagate(m, s, dv)
    return done


@njit(cache=True)
def _add_predecessor(p_head, p_sa, p_edge, p_next, C, sa: int, e: int, s2: int) -> None:
    """Enter edge ``e`` of pair ``sa`` (``s * m + a``) in the predecessor list of ``s2``. (Not inlined at Numba's
    IR level: see the note on :class:`ModelArrays`; it runs once per new edge.)"""
    k = C[N_PREDS]
    C[N_PREDS] = k + 1
    p_sa[k] = sa
    p_edge[k] = e
    p_next[k] = p_head[s2]
    p_head[s2] = k


@njit(cache=True, inline="always")
def record(m: ModelArrays, s: int, a: int, r: float, disc: float, s2: int, sign: int) -> int:
    """Add (``sign`` 1) or remove (-1) one transition ``(s, a) -> s2`` (-1: terminal, :data:`CONT`: goes on) of
    return ``r`` and discount ``disc``; return its edge. A successor seen for the first time takes an edge (and a
    predecessor entry): the caller makes room for one."""
    cnt, cint, rsum, head, C = m.cnt, m.cint, m.rsum, m.head, m.C
    e_to, e_next, e_n, e_disc, e_r = m.e_to, m.e_next, m.e_n, m.e_disc, m.e_r
    cnt[s, a] += sign
    if s2 == CONT:
        cint[s, a] += sign
    rsum[s, a] += sign * r
    if cnt[s, a] == 0:
        rsum[s, a] = 0.0  # (no rounding left over from removed returns)
    e = head[s, a]
    while e >= 0 and e_to[e] != s2:
        e = e_next[e]
    if e < 0:
        e = C[N_EDGES]
        C[N_EDGES] = e + 1
        e_to[e] = s2
        e_next[e] = head[s, a]
        head[s, a] = e
        e_n[e] = 0
        e_disc[e] = 0.0
        e_r[e] = 0.0
        if s2 >= 0:
            _add_predecessor(m.p_head, m.p_sa, m.p_edge, m.p_next, C, s * cnt.shape[1] + a, e, s2)
    e_n[e] += sign
    e_disc[e] += sign * disc
    e_r[e] += sign * r
    if e_n[e] == 0:
        e_disc[e] = 0.0
        e_r[e] = 0.0
    return e


@njit(cache=True, inline="always")
def known(m: ModelArrays, s: int, a: int) -> bool:
    """Whether pair ``(s, a)`` is known: at least ``known`` of its transitions left the cell."""
    return m.cnt[s, a] - m.cint[s, a] >= m.C[KNOWN]


@njit(cache=True, inline="always")
def settled(m: ModelArrays, s: int) -> bool:
    """Every action of ``s`` is :func:`known` (``-1``, the terminal state, and :data:`CONT` are settled):
    ``V(s)`` owes nothing directly to optimism."""
    if s < 0:
        return True
    for a in range(m.cnt.shape[1]):
        if not known(m, s, a):
            return False
    return True


@njit(cache=True, inline="always")
def settle(m: ModelArrays, s: int, budget: int) -> int:
    """Back up ``s`` at once (its statistics changed), queue its predecessors by how much that moved it,
    and sweep at most ``budget`` more states. Returns the backups done."""
    dv = backup(m, s)
    if dv > m.MP[ModelParam.TOL]:
        propagate(m, s, dv)
    return 1 + sweep(m, budget)
