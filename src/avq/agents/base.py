"""What every avq agent shares: parameters, seeding, the ``learn`` budget loop,
episode records and ``predict`` plumbing.

An agent subclass implements the learning itself in three methods:
``_setup()`` (allocate learned state), ``_begin_episode()`` and
``_advance(max_steps)`` (run primitive steps of the current episode). The model
file that ``save`` writes and ``load`` reads is in :mod:`avq.agents.save_util`;
the checks of the hyper-parameters are in :mod:`avq._validate`.
"""

from __future__ import annotations

import inspect
import math
import os
import time
from abc import abstractmethod
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._random import RawStream
from avq._validate import check_bool, check_int, check_optional
from avq.agents import save_util
from avq.agents._history import EpisodeHistory
from avq.agents.callbacks import NEVER, BaseCallback, CallbackList, as_callback
from avq.envs import as_env

__all__ = ["BaseAgent", "EpisodeRecord", "Callback", "NotFiniteError", "load"]

#: One row of the per-episode record.
EpisodeRecord = dict[str, Any]
#: ``callback(agent, record)`` after every episode; returning ``False`` stops ``learn``.
Callback = Callable[["BaseAgent", EpisodeRecord], "bool | None"]


#: The fields every agent records per episode (``episode`` and ``wall_s`` are added by ``learn``).
RECORD_FIELDS = ("steps", "return", "n_cells", "appends", "merges", "refused", "decisions")


class NotFiniteError(ValueError):
    """The environment gave an observation or a reward that is NaN or infinite; the message names the step and
    the episode. Raised by :meth:`BaseAgent.learn` before the agent learns anything from that step."""


def episode_record(
    steps: Any, ret: Any, n_cells: Any, appends: Any, merges: Any = 0, refused: Any = 0, decisions: Any = None
) -> EpisodeRecord:
    """One episode's record with plain Python numbers; ``decisions`` defaults to ``steps``."""
    return {
        "steps": int(steps),
        "return": float(ret),
        "n_cells": int(n_cells),
        "appends": int(appends),
        "merges": int(merges),
        "refused": int(refused),
        "decisions": int(steps if decisions is None else decisions),
    }


class BaseAgent:
    """Base class of avq's agents: what every agent shares (:meth:`learn`, :meth:`predict`,
    :meth:`save`, :meth:`load`, :meth:`get_params`, :meth:`episode_history`).

    Construction stores and checks hyper-parameters only. Learned state lives in
    attributes ending in ``_`` and is created on the first :meth:`learn`. Each agent's
    own parameters and rules are in its class's docstring (`avq.agents.AVQSarsa`, ...).
    """

    #: Registry of learned arrays saved by :meth:`save` (name -> attribute).
    _saved_arrays: ClassVar[tuple[str, ...]] = ()
    #: What ``n_cells`` counts, in messages: cells (states), tiles for tile coding, or actions for the agents
    #: that quantize actions.
    size_unit: ClassVar[str] = "cells"
    #: Attributes that are not pickled, with the value they take in the copy: the compiled entry point of the
    #: last step (avq._numba.direct_call) cannot be pickled, and the next step finds it again.
    _transient: ClassVar[dict[str, Any]] = {}

    def __init__(self, env: gym.Env | str, seed: int | None) -> None:
        self.env = as_env(env)
        self.seed = check_optional(check_int, "seed", seed, 0)
        self._check_spaces(self.env.observation_space, self.env.action_space)
        if isinstance(self.env.action_space, spaces.Discrete):  # (agents for Box actions define their own)
            self.n_actions = int(self.env.action_space.n)
        seq = np.random.SeedSequence(self.seed)
        agent_seq, env_seq, predict_seq = seq.spawn(3)
        self._rng = np.random.default_rng(agent_seq)
        #: The agent's draws for compiled code called once per step (the same stream as ``_rng``).
        self._draws = RawStream(self._rng)
        self._predict_rng = np.random.default_rng(predict_seq)
        self._env_seed: int | None = int(env_seq.generate_state(1)[0])
        self.num_timesteps = 0
        self.num_episodes = 0
        self.history_ = EpisodeHistory()
        self._in_episode = False
        self._wall_s = 0.0
        self._is_setup = False
        #: Which defaults :func:`avq.make_agent` gave this agent (a ``DefaultsUsed``); None when built directly.
        self.defaults_used: Any = None

    # -- parameters (scikit-learn style) ----------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [p for p in sig.parameters if p not in ("self", "env")]

    def get_params(self) -> dict[str, Any]:
        """The constructor's hyper-parameters, read from its signature.

        The values as given, checked and in plain form (floats, lists): the values in
        force unless a parameter leaves something to the environment, such as
        ``AVQSarsa``'s ``scale=None`` (the observation bounds; ``scale_`` holds the
        resolved scale) or ``obs_bounds=None`` (the space's bounds).
        """
        return {name: getattr(self, name) for name in self._param_names()}

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, **self._transient}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    # -- to implement -----------------------------------------------------------------
    @property
    @abstractmethod
    def n_cells(self) -> int:
        """The cells the agent has now (the actions, for the agents that quantize actions: :attr:`size_unit`)."""
        raise NotImplementedError

    def _check_spaces(self, obs_space: spaces.Space, act_space: spaces.Space) -> None:
        raise NotImplementedError

    def _setup(self) -> None:
        raise NotImplementedError

    def _begin_episode(self, obs: np.ndarray) -> None:
        raise NotImplementedError

    def _advance(self, max_steps: int) -> tuple[int, bool]:
        """Run at most ``max_steps`` primitive steps; return (steps run, episode ended)."""
        raise NotImplementedError

    def _end_episode(self) -> EpisodeRecord:
        raise NotImplementedError

    def _fused_runner(self) -> Callable[[int, int, int], tuple[int, np.ndarray, bool]] | None:
        """A compiled loop over environment and agent, when the agent has one for this env.

        It is called as ``runner(max_steps, max_episodes, max_records)`` and returns
        ``(steps, rows, in_episode)``, ``rows`` one per finished episode with the columns of :data:`RECORD_FIELDS`
        (it draws from ``_rng``, ``_draws`` synced before each call). None: step the environment from Python.
        """
        return None

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _check_finite(self, obs: Any, r: Any, step: int) -> None:
        """Refuse an observation or reward that is NaN or infinite, naming the step (0: the reset)."""
        if not (math.isfinite(r) and np.isfinite(obs).all()):
            self._refuse_non_finite(obs, r, step)

    def _refuse_non_finite(self, obs: Any, r: Any, step: int) -> None:
        what = f"reward {r!r}" if not math.isfinite(r) else f"observation {np.asarray(obs).tolist()!r}"
        raise NotFiniteError(
            f"{what} at step {step} of episode {self.num_episodes + 1} is not finite; "
            "avq learns only from finite observations and rewards (check the environment, "
            "or wrap it to end the episode instead)"
        )

    # -- learning -----------------------------------------------------------------------
    def learn(
        self,
        total_episodes: int | None = None,
        total_timesteps: int | None = None,
        callback: BaseCallback | Callback | Sequence[BaseCallback | Callback] | None = None,
        progress_bar: bool = False,
    ) -> BaseAgent:
        """Learn for a number of episodes or of primitive environment steps.

        Exactly one budget must be given. ``learn`` continues where the previous call
        stopped (even inside an episode), so ``learn(a)`` then ``learn(b)`` gives the
        same result as ``learn(a + b)`` with the same seed.

        Args:
            total_episodes: Number of episodes to finish in this call.
            total_timesteps: Number of primitive environment steps to take in this call.
            callback: A :class:`~avq.agents.callbacks.BaseCallback` (for instance a
                :class:`~avq.agents.callbacks.CheckpointCallback`), a function
                ``callback(agent, record)`` called after every episode, or a list of them;
                one that returns ``False`` stops ``learn``.
            progress_bar: Show a tqdm progress bar of the agent's episodes (or steps): it starts
                at those already learned and ends where this call does, and stays on screen.

        Returns:
            self
        """
        if (total_episodes is None) == (total_timesteps is None):
            raise ValueError("give exactly one of total_episodes or total_timesteps")
        if total_episodes is not None:
            check_int("total_episodes", total_episodes, 0)
        if total_timesteps is not None:
            check_int("total_timesteps", total_timesteps, 0)
        callbacks = as_callback(callback, progress_bar=bool(progress_bar))
        if not self._is_setup:
            self._setup()
            self._is_setup = True
        call = _LearnCall(total_timesteps, total_episodes, callbacks, time.perf_counter())
        callbacks.on_learn_start(self, total_episodes, total_timesteps)
        fused = self._fused_runner()
        try:
            while call.budget_left():
                if fused is not None and (self._in_episode or self._env_seed is None):
                    stop = self._learn_fused_chunk(fused, call)
                else:
                    stop = self._learn_python_step(call)
                if stop:
                    break
        finally:
            self._wall_s += call.lap()
            callbacks.on_learn_end(self)
        return self

    @property
    def in_episode(self) -> bool:
        """Whether ``learn`` stopped inside an episode (the next call goes on with it)."""
        return self._in_episode

    def _learn_fused_chunk(
        self, fused: Callable[[int, int, int], tuple[int, np.ndarray, bool]], call: _LearnCall
    ) -> bool:
        """Many steps and episodes in one compiled call (see AVQSarsa's fused loops); True: a callback stops.

        The chunk ends at the budget and where a callback must see an episode.
        """
        budget = min(
            call.episodes_left if call.episodes_left is not None else NEVER, call.callbacks.episodes_to_next_call(self)
        )
        self._draws.sync()  # the loop draws from the agent's generator itself
        n, rows, self._in_episode = fused(
            call.steps_left if call.steps_left is not None else NEVER, budget, min(budget, 1 << 16)
        )
        self.num_timesteps += n
        call.count_steps(self, n)
        elapsed = call.lap()
        # Wall time shared out over the chunk's episodes by their steps.
        wall = self._wall_s + elapsed * np.cumsum(rows[:, 0]) / max(n, 1)
        first = len(self.history_)
        self.history_.extend_block(self.num_episodes + 1, rows, wall)
        self.num_episodes += len(rows)
        self._wall_s += elapsed
        return self._episodes_finished(call, len(rows), (self.history_[k] for k in range(first, len(self.history_))))

    def _learn_python_step(self, call: _LearnCall) -> bool:
        """Step the environment from Python up to the end of the episode or of the step budget
        (resetting it first between episodes); True: a callback stops."""
        if not self._in_episode:
            obs, _ = self.env.reset(seed=self._env_seed)
            self._env_seed = None  # seed once; later resets continue the env's stream
            self._begin_episode(obs)
            self._in_episode = True
        n, ended = self._advance(call.steps_left if call.steps_left is not None else NEVER)
        self.num_timesteps += n
        call.count_steps(self, n)
        if not ended:
            return False
        self._in_episode = False
        self.num_episodes += 1
        self._wall_s += call.lap()
        record = self._end_episode()
        record["episode"] = self.num_episodes
        record["wall_s"] = self._wall_s
        self.history_.append(record)
        return self._episodes_finished(call, 1, (record,))

    def _episodes_finished(self, call: _LearnCall, n: int, records: Iterable[EpisodeRecord]) -> bool:
        """After ``n`` episodes were added to ``history_`` (``records``, which may be none): count them
        against the budget and hand each to the callbacks until one returns ``False``. True: stop."""
        if call.episodes_left is not None:
            call.episodes_left -= n
        if not call.callbacks.callbacks:
            return False  # (no record built: a compiled loop's chunk may hold thousands of short episodes)
        return any(call.callbacks.on_episode_end(self, record) is False for record in records)

    def episode_history(self) -> dict[str, np.ndarray]:
        """The per-episode records as columns (one array per field; empty before the first episode)."""
        return self.history_.columns()

    # -- acting -------------------------------------------------------------------------
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[int | np.ndarray, None]:
        """The action for one observation, or an array of actions for a batch.

        ``deterministic=True`` is the greedy action (lowest index on ties). With
        ``deterministic=False`` the action is ε-greedy, drawn from a generator of its
        own so that queries never change what ``learn`` does. ``state`` and
        ``episode_start`` exist for Stable-Baselines3 compatibility and are unused.
        """
        if not self._is_setup:
            raise RuntimeError(f"{type(self).__name__} has not learned yet; call learn() before predict()")
        check_bool("deterministic", deterministic)
        if isinstance(observation, tuple) and len(observation) == 2 and isinstance(observation[1], dict):
            raise ValueError(
                "predict got an (observation, info) pair; pass the observation alone: obs, info = env.reset()"
            )
        try:
            obs = np.asarray(observation, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"observation must be an array of numbers, not {type(observation).__name__}") from None
        if not np.all(np.isfinite(obs)):
            raise ValueError("observation contains NaN or infinite values")
        shape = self._obs_shape()
        single = obs.shape == shape
        if not single and (obs.ndim != len(shape) + 1 or obs.shape[1:] != shape):
            raise ValueError(
                f"observation has shape {obs.shape}; expected {shape} or a batch (b, {', '.join(map(str, shape))})"
            )
        batch = obs.reshape((1,) + shape) if single else obs
        actions = self._greedy_actions(batch)
        if not deterministic:
            eps = float(getattr(self, "epsilon", 0.0))
            explore = self._predict_rng.random(len(actions)) < eps
            actions = np.where(explore, self._predict_rng.integers(self.n_actions, size=len(actions)), actions)
        return (int(actions[0]), None) if single else (actions.astype(np.int64), None)

    def _obs_shape(self) -> tuple[int, ...]:
        return tuple(self.env.observation_space.shape or ())

    @property
    def wall_s_(self) -> float:
        """Seconds spent in ``learn`` so far (kept in a saved agent)."""
        return self._wall_s

    # -- saving -------------------------------------------------------------------------
    def state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """What :meth:`save` writes: JSON-able counters and random states (``meta``), and the learned arrays.

        Returns:
            ``(meta, arrays)``; ``meta["rng"]`` is the state of the agent's generator
            (``numpy.random.Generator.bit_generator.state``).
        """
        return self._state_dict()

    def _state_dict(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON-able counters and the learned arrays; subclasses extend."""
        self._draws.sync()
        # The environment's generator exists once it was reset (before that, the first reset's seed is saved).
        env_rng = self.env.unwrapped.np_random if self._env_seed is None else None
        meta = {
            "num_timesteps": self.num_timesteps,
            "num_episodes": self.num_episodes,
            "wall_s": self._wall_s,
            "rng": self._rng.bit_generator.state,
            "predict_rng": self._predict_rng.bit_generator.state,
            # The environment's generator, so that resets after loading draw what they would have drawn.
            "env_seed": self._env_seed,
            "env_rng": env_rng.bit_generator.state if isinstance(env_rng, np.random.Generator) else None,
        }
        return meta, {"history": self.history_.as_array()}

    def _load_state_dict(self, meta: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        self.num_timesteps = int(meta["num_timesteps"])
        self.num_episodes = int(meta["num_episodes"])
        self._wall_s = float(meta.get("wall_s", 0.0))
        self._rng.bit_generator.state = meta["rng"]
        self._draws = RawStream(self._rng)  # (no draws from the old state may be served)
        if "predict_rng" in meta:
            self._predict_rng.bit_generator.state = meta["predict_rng"]
        history = arrays.get("history")
        if history is not None:
            self.history_ = EpisodeHistory.from_array(history)
            if len(self.history_) != self.num_episodes:
                raise ValueError(f"the history holds {len(self.history_)} episodes, the counters {self.num_episodes}")
        if meta.get("env_seed") is not None:
            self._env_seed = int(meta["env_seed"])  # saved before the first reset
        elif meta.get("env_rng") is not None:
            bit_generator = getattr(np.random, meta["env_rng"]["bit_generator"])()
            bit_generator.state = meta["env_rng"]
            self.env.unwrapped.np_random = np.random.Generator(bit_generator)
            self._env_seed = None
        else:  # no generator saved: seed the next reset from the agent's seed and the episodes done
            self._env_seed = int(np.random.SeedSequence([self.seed or 0, self.num_episodes]).generate_state(1)[0])

    def save(self, path: str | os.PathLike) -> Path:
        """Save parameters (JSON) and learned arrays (``.npz``) in one zip file.

        Nothing is pickled. The file is written atomically, into a directory that must exist
        (a ``FileNotFoundError`` names it otherwise). Returns the path written (``.zip`` is
        appended when the path has no suffix). The format is described in
        :mod:`avq.agents.save_util`.
        """

        return save_util.save(self, path)

    @classmethod
    def load(cls, path: str | os.PathLike, env: gym.Env | str | None = None) -> BaseAgent:
        """Load an agent saved by :meth:`save`: one of this class or of its subclasses
        (``avq.load``, which is ``BaseAgent.load``, loads any agent)."""
        return save_util.load(path, env=env, classes=_subclasses(cls))


@dataclass
class _LearnCall:
    """What one call of :meth:`BaseAgent.learn` carries from chunk to chunk: the budgets left, the
    callbacks, and the clock of the wall time not yet counted."""

    steps_left: int | None
    episodes_left: int | None
    callbacks: CallbackList
    t0: float

    def budget_left(self) -> bool:
        return (self.steps_left is None or self.steps_left > 0) and (
            self.episodes_left is None or self.episodes_left > 0
        )

    def count_steps(self, agent: BaseAgent, n: int) -> None:
        if self.steps_left is not None:
            self.steps_left -= n
        self.callbacks.on_steps(agent, n)

    def lap(self) -> float:
        """The seconds since the last lap (or the start); the clock starts again."""
        elapsed = time.perf_counter() - self.t0
        self.t0 = time.perf_counter()
        return elapsed


def _subclasses(cls: type[BaseAgent]) -> dict[str, type[BaseAgent]]:
    """``cls`` and every class derived from it, by name: the classes a model file may name."""
    found = {cls.__name__: cls}
    for sub in cls.__subclasses__():
        found.update(_subclasses(sub))
    return found


def load(path: str | os.PathLike, env: gym.Env | str | None = None) -> BaseAgent:
    """Load any avq agent saved with ``agent.save(path)`` (:meth:`BaseAgent.load`)."""
    return BaseAgent.load(path, env=env)
