"""The model file: what ``agent.save`` writes and :func:`load` reads.

A model file is a zip of two members, written atomically and never pickled:

- ``meta.json``: the header (``format``, ``format_version``, ``avq_version``), the
  agent's class and constructor parameters, the spaces and the environment id with
  the ``gymnasium.make`` arguments that rebuild it, and the agent's counters and
  generator states (``state``, from ``agent._state_dict()``);
- ``arrays.npz``: the learned arrays and the episode history, numbers only.

Kept apart from the agents (as Stable-Baselines3 keeps ``common/save_util.py``). It
imports no agent: `avq.agents.BaseAgent.load` hands it the classes a file may name (itself and
its subclasses); `avq.agents.BaseAgent.save` and `avq.load` call it. (Loading a file that records
the agent's ``defaults_used`` imports the registry's ``DefaultsUsed`` then.)
"""

from __future__ import annotations

import inspect
import io
import json
import os
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from avq._io import atomic_write_bytes
from avq._version import __version__
from avq.envs import as_env, recorded_env_id

if TYPE_CHECKING:
    from avq.agents.base import BaseAgent

__all__ = [
    "FORMAT_VERSION", "MODEL_FILES", "save", "load", "env_signature", "check_env_fits", "model_file_in", "recorded_env"
]  # fmt: skip

FORMAT_VERSION = 2
#: Versions this avq reads: 1 (before the history and environment arguments were saved) and 2.
_READABLE_VERSIONS = (1, 2)
#: Parameters added since a file may have been written whose default now behaves otherwise: a file without one
#: loads with the value that keeps what it did (ignore_noise: the noise test of avq.agents._noise, off before;
#: compose_crossings: "noise" now, off before; reweight_when_full: on now, off before).
ADDED_SINCE: dict[str, Any] = {
    "ignore_noise": False, "compose_crossings": False, "reweight_when_full": False, "finer_when_settled": 0
}  # fmt: skip


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


def _describe_space(space: dict[str, Any] | None) -> str:
    """A space as :func:`_space_to_json` gives it, in a line: ``Box(low=[0.0, 0.0], high=[13.0, 11.0])``."""
    if not space:
        return "none recorded"
    if space.get("type") == "Discrete":
        return (
            f"Discrete({space['n']})"
            if space.get("start", 0) == 0
            else f"Discrete({space['n']}, start={space['start']})"
        )
    if space.get("type") == "Box":
        return f"Box(low={space['low']}, high={space['high']})"
    return str(space.get("type"))


def env_signature(env: gym.Env) -> dict[str, Any]:
    """What a model records of the environment it was trained on, as JSON values.

    Returns:
        ``observation_space`` and ``action_space`` (each a dict: type, shape, bounds), ``env_id``
        (None when ``env`` was not made by ``gymnasium.make``; ``module:id`` when it was made from that form,
        so that loading imports the module again) and ``env_make`` (the ``gymnasium.make``
        arguments that rebuild it, or None).
    """
    return {
        "observation_space": _space_to_json(env.observation_space),
        "action_space": _space_to_json(env.action_space),
        "env_id": recorded_env_id(env.spec.id, env.spec.entry_point) if env.spec is not None else None,
        "env_make": _env_make_args(env),
    }


def check_env_fits(trained: dict[str, Any], env: gym.Env, subject: str) -> None:
    """Refuse ``env`` for an agent trained on an environment with other spaces.

    The rule of :func:`load` (with ``env=``) and of :func:`avq.evaluate_maze`: an agent acts
    only in an environment whose observation and action spaces are those it was trained on.
    On the mazes the observation bounds are the layout's size, so a layout of another size
    is refused.

    Args:
        trained: What the agent was trained on: :func:`env_signature` of its environment, or a
            model file's header (which holds the same keys).
        env: The environment offered.
        subject: Who refuses, the start of the message (a model file's path, a function's name).

    Raises:
        ValueError: naming the space that differs, both versions of it, the environment the agent was
            trained on, and what to pass instead.
    """
    for key in ("observation_space", "action_space"):
        want, have = trained.get(key), _space_to_json(getattr(env, key))
        if want != have:
            origin = trained.get("env_id") or "an environment without a registered id"
            make = trained.get("env_make") or {}
            if make:
                origin += " with " + ", ".join(f"{k}={v!r}" for k, v in make.items())
            raise ValueError(
                f"{subject}: the agent was trained on {origin}, whose {key} is {_describe_space(want)}, but env's is "
                f"{_describe_space(have)}; pass an environment made like the one it was trained on (the same id and "
                "gymnasium.make arguments: on a maze, the same layout)"
            )


def save(agent: BaseAgent, path: str | os.PathLike) -> Path:
    """Write ``agent`` to a model file at ``path`` (``.zip`` appended when it has no suffix); return the path.

    The directory must exist, as for ``numpy.save`` and Stable-Baselines3: a ``FileNotFoundError`` names it
    otherwise (a mistyped path does not make directories)."""
    path = Path(path)
    if path.is_dir() or not path.name:
        raise ValueError(f"{path} is a directory; give a file name such as {path / 'model.zip'}")
    if path.suffix == "":
        path = path.with_suffix(".zip")
    existing = next(p for p in path.absolute().parents if os.path.exists(p))
    if existing != path.absolute().parent and os.path.isdir(existing):  # (under a file: the write says so)
        raise FileNotFoundError(
            f"cannot save to {path}: the directory {path.parent} does not exist; create it first "
            f"(os.makedirs({str(path.parent)!r})) or give a path in an existing directory"
        )
    state, arrays = agent._state_dict()
    used = agent.defaults_used
    meta = {
        "format": "avq-agent",
        "format_version": FORMAT_VERSION,
        "avq_version": __version__,
        "class": type(agent).__name__,
        "params": agent.get_params(),
        **env_signature(agent.env),
        # (which defaults avq.make_agent gave it: the agent's name, for avq evaluate; None when built directly)
        "defaults_used": None if used is None else json.loads(json.dumps(used._asdict(), default=_plain_json)),
        "state": state,
    }
    buf = io.BytesIO()
    # (mypy takes **arrays as possibly filling savez's allow_pickle: bool; the names are the saved arrays')
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meta.json", json.dumps(meta, indent=1))
        zf.writestr("arrays.npz", buf.getvalue())
    atomic_write_bytes(path, out.getvalue())
    return path


def _plain_json(value: Any) -> Any:
    """A value JSON cannot hold as it is: an array's list, else its repr."""
    return value.tolist() if hasattr(value, "tolist") else repr(value)


#: The model files avq writes into a directory, the one to give first: a run's, a stopped run's, an evaluation's.
MODEL_FILES = ("model.zip", "checkpoint.zip", "best.zip")


def model_file_in(directory: str | os.PathLike) -> Path | None:
    """The first of :data:`MODEL_FILES` in ``directory``, for a message to a user who gave the directory; None."""
    return next((Path(directory) / name for name in MODEL_FILES if (Path(directory) / name).is_file()), None)


def recorded_env(path: str | os.PathLike) -> tuple[str | None, dict[str, Any] | None]:
    """The environment id (``module:id`` where it records the module) and the ``gymnasium.make`` arguments that a
    model file records; None where it records none. A ValueError when ``path`` is no readable model file."""
    meta, _ = _read_model_file(Path(path), header_only=True)
    return meta.get("env_id"), meta.get("env_make")


def _read_model_file(path: Path, header_only: bool = False) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """A model file's header and arrays, checked (``header_only``: its header alone, the arrays not read)."""
    if path.is_dir():
        inside = model_file_in(path)
        raise ValueError(
            f"{path} is a directory, not a model file; "
            + (f"give the model file in it: {inside}" if inside else "give a model file written by agent.save")
        )
    try:
        with zipfile.ZipFile(path) as zf:
            meta = json.loads(zf.read("meta.json").decode("utf-8"))
            raw = b"" if header_only else zf.read("arrays.npz")
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
    if header_only:
        return meta, {}
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


def load(
    path: str | os.PathLike, env: gym.Env | str | None = None, *, classes: dict[str, type[BaseAgent]]
) -> BaseAgent:
    """Load an avq agent saved with ``agent.save(path)`` (``avq.load`` and ``Agent.load`` call this).

    Args:
        path: The saved file (``.zip`` is tried when the path has no suffix).
        env: The environment to attach (or a registered id). Without one, the environment is
            made from the id and ``gymnasium.make`` arguments stored in the file.
        classes: The classes the file may name, by name (the file names its class).

    Returns:
        The agent as it was saved, with its generators: learning on continues as the
        uninterrupted run would have (when it was saved between episodes).

    Raises:
        FileNotFoundError: no file at ``path``.
        ValueError: the file is not an avq model or is damaged, or ``env``'s spaces are not
            those the agent was trained on (:func:`avq.agents.save_util.check_env_fits`).
    """
    path = Path(path)
    if not path.exists() and path.suffix == "" and path.with_suffix(".zip").exists():
        path = path.with_suffix(".zip")
    meta, arrays = _read_model_file(path)
    cls = classes.get(meta.get("class", ""))
    if cls is None:
        want = next(iter(classes))  # (the class asked for; its subclasses follow)
        raise ValueError(
            f"{path}: holds a {meta.get('class')}, not a {want}"
            if want != "BaseAgent"
            else f"{path}: unknown agent class {meta.get('class')!r}"
        )
    if env is None:
        if not meta.get("env_id"):
            raise ValueError(f"{path}: the model records no environment id; pass env= to load it")
        make = meta.get("env_make")
        if meta.get("format_version", 1) >= 2 and make is None:
            raise ValueError(
                f"{path}: the environment's gymnasium.make arguments could not be saved; pass env= to load it"
            )
        try:
            env = as_env(meta["env_id"], **(make or {}))
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}; pass env= to load it") from None
    params = dict(meta["params"])
    for name, before in ADDED_SINCE.items():  # (a file from before the parameter keeps its behaviour)
        if name not in params and name in inspect.signature(cls).parameters:
            params[name] = before
    env = as_env(env)
    check_env_fits(meta, env, str(path))
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
    used = meta.get("defaults_used")
    if isinstance(used, dict) and set(used) == {"name", "env_id", "key", "explicit"}:
        from avq.agents.registry import DefaultsUsed  # (the registry imports the agents, which import this)

        agent.defaults_used = DefaultsUsed(**used)
    return agent
