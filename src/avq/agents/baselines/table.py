"""What the table agents share (``tabular``, ``grid``): Sarsa(λ) with one decision per primitive step on the
rows of a table, and the one step loop that runs it from Python.

A subclass says how an observation finds its row (:meth:`TableSarsa._row`, which hands out a new row
on a first visit); the step itself is :func:`avq.agents._td.table_step`, the same compiled function
the fused loop of ``tabular`` calls. Every observation reached gets a row, the terminal one included
(so ``n_cells`` counts every observation or bin seen), although a terminal row is never learned from.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from avq._validate import SarsaSettings
from avq.agents._per_step import PerStepAgent
from avq.agents._td import SarsaParams, clear_traces, decide, table_step
from avq.agents.base import EpisodeRecord, episode_record

__all__ = ["TableSarsa", "observation_key", "greedy_over_rows"]


def observation_key(space: Any, obs: Any) -> Any:
    """The key of one observation in a table of distinct observations: the index of a ``Discrete`` space,
    else the observation as a tuple of floats (its shape checked against the space's)."""
    if isinstance(space, spaces.Discrete):
        return int(obs)
    x = np.asarray(obs, dtype=np.float64)
    if x.shape != space.shape:
        raise ValueError(f"observation has shape {x.shape}; the space says {space.shape}")
    return tuple(x.tolist())


def greedy_over_rows(space: Any, obs: np.ndarray, row: Any, Q: np.ndarray) -> np.ndarray:
    """The greedy action (lowest index on ties) of each observation of a batch from the rows of ``Q``;
    ``row(o, create=False)`` gives an observation's row, -1 for one never seen (action 0). Observations
    of a ``Discrete`` space must be in it."""
    if isinstance(space, spaces.Discrete):
        bad = [o for o in obs if o != int(o) or not space.contains(int(o))]
        if bad:
            raise ValueError(f"observation {bad[0]!r} is not in the observation space {space}")
    out = np.zeros(len(obs), dtype=np.int64)
    for b, o in enumerate(obs):
        r = row(o, create=False)
        if r >= 0:
            out[b] = int(Q[r].argmax())
    return out


class TableSarsa(SarsaSettings, PerStepAgent):
    """Base of the table agents: ``_q``, ``_e`` ``(rows, m)``, the active list ``_act`` of
    :mod:`avq.agents._td`, ``_n`` rows in use; the episode's row, action, steps, return and new rows."""

    def _row(self, obs: Any) -> int:
        """The row of ``obs``, handed out (and counted in ``_ep_new``) on a first visit."""
        raise NotImplementedError

    def _make_table(self, rows: int) -> None:
        self._q = np.full((rows, self.n_actions), self.q_init)
        self._e = np.zeros((rows, self.n_actions))
        self._act = np.zeros(rows + 1, dtype=np.int64)
        self._n = 0
        self._ep_row = 0
        self._ep_action = 0
        self._ep_steps = 0
        self._ep_return = 0.0
        self._ep_new = 0

    def _grow_table(self, rows: int) -> None:
        """At least ``rows`` rows, new ones at ``q_init`` (doubling, so that growth is rare)."""
        cap = self._q.shape[0]
        if rows <= cap:
            return
        new = max(rows, 2 * cap)
        self._q = np.concatenate([self._q, np.full((new - cap, self.n_actions), self.q_init)])
        self._e = np.concatenate([self._e, np.zeros((new - cap, self.n_actions))])
        self._act = np.concatenate([self._act, np.zeros(new - cap, dtype=np.int64)])

    @property
    def n_cells(self) -> int:
        return self._n if self._is_setup else 0

    def _begin_episode(self, obs: Any) -> None:
        clear_traces(self._e, self._act)
        self._ep_steps = 0
        self._ep_return = 0.0
        self._ep_new = 0
        self._check_finite(obs, 0.0, 0)
        self._ep_row = self._row(obs)
        self._draws.reserve()
        self._ep_action = int(decide(self._draws.src, self._q, self._ep_row, self.epsilon))

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        draws = self._draws
        sp = SarsaParams(self.epsilon, self.alpha, self.gamma, self.lam, self.traces == "replacing")

        def update(s: int, a: int, r: float, obs: Any, terminated: bool) -> tuple[int, int]:
            s2 = self._row(obs)
            draws.reserve()
            return s2, int(table_step(draws.src, self._q, self._e, self._act, s, a, r, s2, terminated, sp))

        self._ep_row, self._ep_action, n, ended = self._sarsa_steps(max_steps, self._ep_row, self._ep_action, update)
        return n, ended

    def _end_episode(self) -> EpisodeRecord:
        return episode_record(self._ep_steps, self._ep_return, self._n, self._ep_new)
