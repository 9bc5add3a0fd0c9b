"""What every avq agent shares: parameters, seeding, the ``learn`` budget loop,
episode records, ``predict`` plumbing and saving.

An agent subclass implements the learning itself in three methods:
``_setup()`` (allocate learned state), ``_begin_episode()`` and
``_advance(max_steps)`` (run primitive steps of the current episode).
"""

from __future__ import annotations

import inspect
import io
import json
import math
import os
import time
import zipfile
from pathlib import Path
from typing import Any, Callable, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._io import ProgressLog, atomic_write_bytes
from avq._random import RawStream
from avq.agents._td import decide
from avq.agents._history import EpisodeHistory

__all__ = ["BaseAgent", "EpisodeRecord", "Callback", "load"]

FORMAT_VERSION = 2
#: Versions this avq reads: 1 (before the history and environment arguments were saved) and 2.
_READABLE_VERSIONS = (1, 2)

#: One row of the per-episode record.
EpisodeRecord = dict[str, Any]
#: ``callback(agent, record)`` after every episode; returning ``False`` stops ``learn``.
Callback = Callable[["BaseAgent", EpisodeRecord], "bool | None"]

_AGENT_CLASSES: dict[str, type["BaseAgent"]] = {}

#: The fields every agent records per episode (``episode`` and ``wall_s`` are added by ``learn``).
RECORD_FIELDS = ("steps", "return", "n_cells", "appends", "merges", "refused", "decisions")
#: The columns of ``progress.csv``.
PROGRESS_COLUMNS = ("episode", "steps", "return", "n_cells", "appends", "merges", "wall_s")


def episode_record(steps: Any, ret: Any, n_cells: Any, appends: Any, merges: Any = 0, refused: Any = 0,
                   decisions: Any = None) -> EpisodeRecord:
    """One episode's record with plain Python numbers; ``decisions`` defaults to ``steps``."""
    return {
        "steps": int(steps), "return": float(ret), "n_cells": int(n_cells), "appends": int(appends),
        "merges": int(merges), "refused": int(refused), "decisions": int(steps if decisions is None else decisions),
    }


def _make_env(env: gym.Env | str, **make_args: Any) -> gym.Env:
    if isinstance(env, str):
        import avq.envs  # noqa: F401  (registers avq's environments)

        try:
            return gym.make(env, **make_args)
        except (gym.error.Error, TypeError) as exc:
            raise ValueError(f"cannot make environment {env!r}: {exc}") from None
    if not isinstance(env, gym.Env):
        raise TypeError(f"env must be a gymnasium.Env or a registered id, not {type(env).__name__}")
    return env


def check_range(name: str, value: Any, low: float, high: float, *, low_open: bool = False, high_open: bool = False) -> float:
    """Return ``value`` as a float if it lies in the interval, else raise a ``ValueError`` naming it."""
    lb = "(" if low_open else "["
    rb = ")" if high_open else "]"
    interval = f"{lb}{low}, {high}{rb}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number in {interval}, not {value!r}")
    v = float(value)
    ok = np.isfinite(v) or (v == high and high == np.inf)
    ok = ok and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
    if not ok:
        raise ValueError(f"{name} must be in {interval}, not {value!r}")
    return v


def check_int(name: str, value: Any, low: int, *, allow_none: bool = False) -> int | None:
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        kind = f"an integer >= {low}" + (" or None" if allow_none else "")
        raise ValueError(f"{name} must be {kind}, not {value!r}")
    return int(value)


def check_sarsa_params(agent: Any, alpha: Any, lam: Any, gamma: Any, epsilon: Any, q_init: Any, traces: Any) -> None:
    """Check and store the hyper-parameters every Sarsa(λ) agent shares."""
    agent.alpha = check_range("alpha", alpha, 0.0, 1.0, low_open=True)
    agent.lam = check_range("lam", lam, 0.0, 1.0)
    agent.gamma = check_range("gamma", gamma, 0.0, 1.0)
    agent.epsilon = check_range("epsilon", epsilon, 0.0, 1.0)
    agent.q_init = check_range("q_init", q_init, -np.inf, np.inf, low_open=True, high_open=True)
    if traces not in ("replacing", "accumulating"):
        raise ValueError(f"traces must be 'replacing' or 'accumulating', not {traces!r}")
    agent.traces = traces


def _env_make_args(env: gym.Env) -> dict[str, Any] | None:
    """The ``gymnasium.make`` arguments that rebuild ``env`` (its kwargs and step limit), if JSON can hold them."""
    spec = getattr(env, "spec", None)
    if spec is None:
        return None
    args = dict(spec.kwargs or {})
    if spec.max_episode_steps is not None:
        args["max_episode_steps"] = int(spec.max_episode_steps)
    try:
        return json.loads(json.dumps(args))
    except (TypeError, ValueError):
        return None


def _space_to_json(space: spaces.Space) -> dict[str, Any]:
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    if isinstance(space, spaces.Box):
        return {
            "type": "Box",
            "shape": list(space.shape),
            "low": np.asarray(space.low, dtype=np.float64).ravel().tolist(),
            "high": np.asarray(space.high, dtype=np.float64).ravel().tolist(),
        }
    return {"type": type(space).__name__}


class BaseAgent:
    """Base class of avq's agents (see :class:`avq.AVQSarsa` for the full API).

    Construction stores and checks hyper-parameters only. Learned state lives in
    attributes ending in ``_`` and is created on the first :meth:`learn`.
    """

    #: Registry of learned arrays saved by :meth:`save` (name -> attribute).
    _saved_arrays: ClassVar[tuple[str, ...]] = ()
    #: What ``n_cells`` counts, in messages: cells (states), or actions for the agents that quantize actions.
    size_unit: ClassVar[str] = "cells"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        _AGENT_CLASSES[cls.__name__] = cls

    def __init__(self, env: gym.Env | str, seed: int | None) -> None:
        self.env = _make_env(env)
        self.seed = check_int("seed", seed, 0, allow_none=True)
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

    # -- parameters (scikit-learn style) ----------------------------------------------
    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [p for p in sig.parameters if p not in ("self", "env")]

    def get_params(self) -> dict[str, Any]:
        """The constructor's hyper-parameters, read from its signature."""
        return {name: getattr(self, name) for name in self._param_names()}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"

    # -- to implement -----------------------------------------------------------------
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
        ``(steps, rows, in_episode)``, ``rows`` one per finished episode with the
        columns of :data:`RECORD_FIELDS`. None: step the environment from Python.
        """
        return None

    def _greedy_actions(self, obs: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _decide(self, values: np.ndarray) -> int:
        """ε-greedy over one profile of action values (:func:`avq.agents._td.epsilon_greedy`), drawn
        from the agent's stream."""
        self._draws.reserve(16)
        return int(decide(self._draws.src, values.reshape(1, -1), 0, self.epsilon))

    def _check_finite(self, obs: Any, r: Any, step: int) -> None:
        """Refuse an observation or reward that is NaN or infinite, naming the step (0: the reset)."""
        if not (math.isfinite(r) and np.isfinite(obs).all()):
            self._refuse_non_finite(obs, r, step)

    def _refuse_non_finite(self, obs: Any, r: Any, step: int) -> None:
        what = f"reward {r!r}" if not math.isfinite(r) else f"observation {np.asarray(obs).tolist()!r}"
        raise ValueError(f"{what} at step {step} of episode {self.num_episodes + 1} is not finite; "
                         "avq learns only from finite observations and rewards (check the environment, "
                         "or wrap it to end the episode instead)")

    # -- learning -----------------------------------------------------------------------
    def learn(
        self,
        total_episodes: int | None = None,
        total_timesteps: int | None = None,
        callback: Callback | None = None,
        progress_bar: bool = False,
        checkpoint_every: int | None = None,
        checkpoint_dir: str | os.PathLike | None = None,
    ) -> "BaseAgent":
        """Learn for a number of episodes or of primitive environment steps.

        Exactly one budget must be given. ``learn`` continues where the previous call
        stopped (even inside an episode), so ``learn(a)`` then ``learn(b)`` gives the
        same result as ``learn(a + b)`` with the same seed.

        Args:
            total_episodes: Number of episodes to finish in this call.
            total_timesteps: Number of primitive environment steps to take in this call.
            callback: ``callback(agent, record)`` after every episode; ``False`` stops.
            progress_bar: Show a tqdm progress bar.
            checkpoint_every: Every this many episodes (counted from the agent's
                first episode), save the agent to ``checkpoint_dir/checkpoint.zip``
                and bring ``checkpoint_dir/progress.csv`` (one row per episode) up
                to date, both written so that a crash leaves a complete file.
                Loading the checkpoint (:func:`avq.load`) and learning on gives
                bit for bit what learning on without the stop would have given.
            checkpoint_dir: Where checkpoints go; required with ``checkpoint_every``.

        Returns:
            self
        """
        if (total_episodes is None) == (total_timesteps is None):
            raise ValueError("give exactly one of total_episodes or total_timesteps")
        if total_episodes is not None:
            check_int("total_episodes", total_episodes, 0)
        if total_timesteps is not None:
            check_int("total_timesteps", total_timesteps, 0)
        if callback is not None and not callable(callback):
            raise TypeError("callback must be callable as callback(agent, record)")
        if (checkpoint_every is None) != (checkpoint_dir is None):
            raise ValueError("give checkpoint_every and checkpoint_dir together")
        every = None if checkpoint_every is None else int(check_int("checkpoint_every", checkpoint_every, 1))
        checkpoint = None
        if checkpoint_dir is not None:
            checkpoint = Path(checkpoint_dir)
            if checkpoint.exists() and not checkpoint.is_dir():
                raise ValueError(f"checkpoint_dir {checkpoint} is a file; give a directory")
            log = ProgressLog(checkpoint / "progress.csv", PROGRESS_COLUMNS)
        if not self._is_setup:
            self._setup()
            self._is_setup = True
        bar = None
        if progress_bar:
            from tqdm.auto import tqdm

            total = total_episodes if total_episodes is not None else total_timesteps
            unit = "episode" if total_episodes is not None else "step"
            bar = tqdm(total=total, unit=unit, desc=type(self).__name__, leave=False)
        steps_left = total_timesteps
        episodes_left = total_episodes
        t0 = time.perf_counter()
        fused = self._fused_runner()
        try:
            while (steps_left is None or steps_left > 0) and (episodes_left is None or episodes_left > 0):
                if fused is not None and (self._in_episode or self._env_seed is None):
                    # Many steps and episodes in one compiled call (see AVQSarsa's fused loops).
                    chunk = 1 if callback is not None else (64 if bar is not None else 1 << 16)
                    budget = episodes_left if episodes_left is not None else 1 << 62
                    if every is not None:  # stop at the next checkpoint
                        budget = min(budget, every - self.num_episodes % every)
                    n, rows, self._in_episode = fused(
                        steps_left if steps_left is not None else 1 << 62, budget, chunk)
                    self.num_timesteps += n
                    if steps_left is not None:
                        steps_left -= n
                        if bar is not None:
                            bar.update(n)
                    elapsed = time.perf_counter() - t0
                    t0 = time.perf_counter()
                    # Wall time shared out over the chunk's episodes by their steps.
                    wall = self._wall_s + elapsed * np.cumsum(rows[:, 0]) / max(n, 1)
                    first = len(self.history_)
                    self.history_.extend_block(self.num_episodes + 1, rows, wall)
                    self.num_episodes += len(rows)
                    self._wall_s += elapsed
                    if episodes_left is not None:
                        episodes_left -= len(rows)
                        if bar is not None:
                            bar.update(len(rows))
                    stop = callback is not None and any(
                        callback(self, self.history_[k]) is False for k in range(first, len(self.history_)))
                    if every is not None and len(rows) and not self._in_episode and self.num_episodes % every == 0:
                        self._checkpoint(checkpoint, log)
                    if stop:
                        break
                    continue
                if not self._in_episode:
                    obs, _ = self.env.reset(seed=self._env_seed)
                    self._env_seed = None  # seed once; later resets continue the env's stream
                    self._begin_episode(obs)
                    self._in_episode = True
                n, ended = self._advance(steps_left if steps_left is not None else 1 << 62)
                self.num_timesteps += n
                if steps_left is not None:
                    steps_left -= n
                    if bar is not None:
                        bar.update(n)
                if ended:
                    self._in_episode = False
                    self.num_episodes += 1
                    self._wall_s += time.perf_counter() - t0
                    t0 = time.perf_counter()
                    record = self._end_episode()
                    record["episode"] = self.num_episodes
                    record["wall_s"] = self._wall_s
                    self.history_.append(record)
                    if episodes_left is not None:
                        episodes_left -= 1
                        if bar is not None:
                            bar.update(1)
                    stop = callback is not None and callback(self, record) is False
                    if every is not None and self.num_episodes % every == 0:
                        self._checkpoint(checkpoint, log)
                    if stop:
                        break
        finally:
            self._wall_s += time.perf_counter() - t0
            if bar is not None:
                bar.close()
        if checkpoint is not None:
            log.sync(self.history_)  # the episodes after the last checkpoint too (a resume drops them again)
        return self

    def _checkpoint(self, directory: Path, log: "ProgressLog") -> None:
        log.sync(self.history_)
        self.save(directory / "checkpoint.zip")

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
        if not isinstance(deterministic, (bool, np.bool_)):
            raise ValueError(f"deterministic must be True or False, not {deterministic!r}")
        if isinstance(observation, tuple) and len(observation) == 2 and isinstance(observation[1], dict):
            raise ValueError("predict got an (observation, info) pair; pass the observation alone: obs, info = env.reset()")
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

    # -- saving -------------------------------------------------------------------------
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

        Nothing is pickled. The file is written atomically. Returns the path written
        (``.zip`` is appended when the path has no suffix).
        """
        from avq import __version__

        path = Path(path)
        if path.is_dir() or not path.name:
            raise ValueError(f"{path} is a directory; give a file name such as {path / 'model.zip'}")
        if path.suffix == "":
            path = path.with_suffix(".zip")
        state, arrays = self._state_dict()
        meta = {
            "format": "avq-agent",
            "format_version": FORMAT_VERSION,
            "avq_version": __version__,
            "class": type(self).__name__,
            "params": self.get_params(),
            "observation_space": _space_to_json(self.env.observation_space),
            "action_space": _space_to_json(self.env.action_space),
            "env_id": getattr(getattr(self.env, "spec", None), "id", None),
            "env_make": _env_make_args(self.env),
            "state": state,
        }
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        out = io.BytesIO()
        with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("meta.json", json.dumps(meta, indent=1))
            zf.writestr("arrays.npz", buf.getvalue())
        atomic_write_bytes(path, out.getvalue())
        return path

    @classmethod
    def load(cls, path: str | os.PathLike, env: gym.Env | str | None = None) -> "BaseAgent":
        """Load an agent saved by :meth:`save`; see :func:`avq.load`."""
        agent = load(path, env=env)
        if not isinstance(agent, cls):
            raise ValueError(f"{path}: holds a {type(agent).__name__}, not a {cls.__name__}")
        return agent


def _read_model_file(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    try:
        with zipfile.ZipFile(path) as zf:
            meta = json.loads(zf.read("meta.json").decode("utf-8"))
            raw = zf.read("arrays.npz")
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such model file") from None
    except Exception as exc:  # noqa: BLE001  (a damaged file can fail anywhere in zipfile: BadZipFile, zlib.error,
        # NotImplementedError for flags it cannot read, RuntimeError for encryption, struct or JSON errors...)
        raise ValueError(f"{path}: not a readable avq model file ({type(exc).__name__}: {exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != "avq-agent":
        raise ValueError(f"{path}: not an avq model file (no avq-agent header)")
    if meta.get("format_version") not in _READABLE_VERSIONS:
        raise ValueError(
            f"{path}: model format version {meta.get('format_version')} is not supported "
            f"(this avq reads versions {', '.join(map(str, _READABLE_VERSIONS))})"
        )
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except Exception as exc:  # noqa: BLE001  (as above: any failure to parse is an unreadable file)
        raise ValueError(f"{path}: the model's arrays are unreadable ({exc})") from None
    for name, arr in arrays.items():
        if arr.dtype.kind not in "biuf":
            raise ValueError(f"{path}: array {name!r} has dtype {arr.dtype}; a model holds only numbers")
        if arr.dtype.kind == "f" and not np.isfinite(arr).all():
            raise ValueError(f"{path}: array {name!r} holds NaN or infinite values")
    for key, kind in (("params", dict), ("state", dict), ("class", str)):
        if not isinstance(meta.get(key), kind):
            raise ValueError(f"{path}: the model's header has no valid {key!r}")
    return meta, arrays


def load(path: str | os.PathLike, env: gym.Env | str | None = None) -> BaseAgent:
    """Load any avq agent saved with ``agent.save(path)``.

    Args:
        path: The saved file.
        env: The environment to attach. Without one, the environment is made from
            the id stored in the file (which must be registered).

    Raises:
        ValueError: the file is not an avq model, is damaged, or its spaces do not
            match ``env``'s.
    """
    path = Path(path)
    if not path.exists() and path.suffix == "" and path.with_suffix(".zip").exists():
        path = path.with_suffix(".zip")
    meta, arrays = _read_model_file(path)
    cls = _AGENT_CLASSES.get(meta.get("class", ""))
    if cls is None:
        raise ValueError(f"{path}: unknown agent class {meta.get('class')!r}")
    if env is None:
        if not meta.get("env_id"):
            raise ValueError(f"{path}: the model records no environment id; pass env= to load it")
        make = meta.get("env_make")
        if meta.get("format_version", 1) >= 2 and make is None:
            raise ValueError(f"{path}: the environment's gymnasium.make arguments could not be saved; "
                             "pass env= to load it")
        try:
            env = _make_env(meta["env_id"], **(make or {}))
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}; pass env= to load it") from None
    params = dict(meta["params"])
    env = _make_env(env)
    for key in ("observation_space", "action_space"):
        want = meta.get(key)
        have = _space_to_json(getattr(env, key))
        if want != have:
            raise ValueError(f"{path}: the model was saved for {key} {want}, but env has {have}")
    try:
        agent = cls(env, **params)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: the saved parameters are not valid for {cls.__name__} ({exc})") from None
    agent._setup()
    agent._is_setup = True
    if meta["format_version"] >= 2 and "history" not in arrays:
        raise ValueError(f"{path}: the model's state is incomplete (no history array)")
    try:
        agent._load_state_dict(meta["state"], arrays)
    except (KeyError, ValueError, IndexError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path}: the model's state is incomplete or inconsistent ({exc})") from None
    return agent
