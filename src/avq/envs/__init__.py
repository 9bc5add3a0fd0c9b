"""Environments shipped with avq, registered with Gymnasium on import."""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
import traceback
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from typing import Any

import gymnasium as gym

from avq.envs.grid_maze import GridMaze
from avq.envs.irrelevant import IrrelevantDims
from avq.envs.layouts import MAPS, Layout, load_layout, parse_layout, random_layout, refine_layout
from avq.envs.robot_maze import RobotMaze
from avq.envs.shaping import PotentialShaping
from avq.envs.slab_maze import SlabMaze

__all__ = [
    "as_env",
    "GridMaze",
    "RobotMaze",
    "SlabMaze",
    "IrrelevantDims",
    "PotentialShaping",
    "MAPS",
    "Layout",
    "load_layout",
    "parse_layout",
    "random_layout",
    "refine_layout",
    "recorded_env_id",
    "same_env",
    "register_envs",
    "split_env_id",
]


def register_envs() -> None:
    """Register ``avq/GridMaze-v0``, ``avq/RobotMaze-v0`` and ``avq/SlabMaze-v0`` (idempotent).

    RobotMaze and SlabMaze are registered without ``max_episode_steps``: they truncate by
    themselves after ``max_steps`` steps, a limit that scales with their ``move`` argument
    (and SlabMaze's with its dimension).
    """
    if "avq/GridMaze-v0" not in gym.registry:
        gym.register(
            id="avq/GridMaze-v0",
            entry_point="avq.envs.grid_maze:GridMaze",
            max_episode_steps=100,
        )
    if "avq/RobotMaze-v0" not in gym.registry:
        gym.register(
            id="avq/RobotMaze-v0",
            entry_point="avq.envs.robot_maze:RobotMaze",
        )
    if "avq/SlabMaze-v0" not in gym.registry:
        gym.register(id="avq/SlabMaze-v0", entry_point="avq.envs.slab_maze:SlabMaze")


register_envs()


#: The module that registered each id made from Gymnasium's ``module:id`` form in this process: a saved model
#: records the id with its module (:func:`recorded_env_id`), so that loading it imports the module again.
_REGISTERED_BY: dict[str, str] = {}


def split_env_id(env_id: str) -> tuple[str | None, str]:
    """``("mymodule", "user/Nav3D-v0")`` for Gymnasium's ``"mymodule:user/Nav3D-v0"``; ``(None, env_id)`` without a
    module."""
    module, sep, name = env_id.rpartition(":")
    return (module, name) if sep else (None, env_id)


#: Packages whose ids are registered once they are imported with avq: a file records their ids without a module.
_ALWAYS_REGISTERED = ("gymnasium", "avq")


def recorded_env_id(env_id: str, entry_point: Any = None) -> str:
    """``env_id`` as a file should record it, so that loading it in another process makes the environment again:
    with the module that registered it, if that was given as ``module:id`` in this process
    (``"mymodule:user/Nav3D-v0"``); else with the module of its ``entry_point`` (its spec's: a ``"module:Class"``
    string, or a class or function, a ``functools.partial``'s function) where that is a module an import finds
    by its name and neither Gymnasium's nor avq's (a module that registers its own class, as Gymnasium's do; not a
    script's ``__main__``, nor a file run or loaded by its path); else as it is."""
    if split_env_id(env_id)[0] is not None:
        return env_id
    module = _REGISTERED_BY.get(env_id) or _entry_point_module(entry_point)
    return f"{module}:{env_id}" if module else env_id


def _entry_point_module(entry_point: Any) -> str | None:
    """The module of an entry point, if an import finds it by that name and it is not one of
    :data:`_ALWAYS_REGISTERED`; else None."""
    if isinstance(entry_point, str):
        name = entry_point.partition(":")[0]
    else:
        name = getattr(getattr(entry_point, "func", entry_point), "__module__", None) or ""
    if not name or name == "__main__" or name.split(".")[0] in _ALWAYS_REGISTERED:
        return None
    try:
        found = importlib.util.find_spec(name)
    except (ImportError, ValueError):  # (a parent package that is not there; a name that is no module's)
        return None
    return name if found is not None and found.name == name else None


@contextmanager
def _cwd_on_path() -> Iterator[str]:
    """The working directory first on ``sys.path`` while the block runs, as ``python -m`` puts it."""
    cwd = os.getcwd()
    sys.path.insert(0, cwd)
    try:
        yield cwd
    finally:
        with suppress(ValueError):
            sys.path.remove(cwd)  # (the first occurrence: the one inserted)


def _import_registering_module(module: str, env_id: str) -> None:
    """Import ``module``, which registers ``env_id``, from the working directory or the Python path; a
    ``ValueError`` naming the module, what went wrong and what to do when it cannot be imported."""
    given = f"{module}:{env_id}"
    with _cwd_on_path() as cwd:
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name is not None and (module == exc.name or module.startswith(exc.name + ".")):
                file = module.replace(".", os.sep) + ".py"
                raise ValueError(
                    f"environment {given!r}: no module named {module!r} in the working directory {cwd} nor on the "
                    f"Python path; run avq from the directory that holds {file} (or put that directory on "
                    "PYTHONPATH), or correct the module's name before the ':'"
                ) from None
            raise ValueError(
                f"environment {given!r}: importing module {module!r} failed: it imports {exc.name!r}, which is not "
                f"installed; install it (pip install {exc.name.split('.')[0] if exc.name else '...'})"
            ) from None
        except Exception as exc:  # noqa: BLE001  (any error of the user's module: say where, without a traceback)
            frames = [f for f in traceback.extract_tb(exc.__traceback__) if "importlib" not in f.filename]
            if isinstance(exc, SyntaxError):  # (where the module's text is wrong, not where it was imported)
                what, where = exc.msg, f" ({exc.filename}, line {exc.lineno})"
            else:
                what, where = str(exc), f" ({frames[-1].filename}, line {frames[-1].lineno})" if frames else ""
            raise ValueError(
                f"environment {given!r}: importing module {module!r} failed with {type(exc).__name__}: {what}{where}; "
                "fix the module (python -c 'import " + module + "' shows the traceback)"
            ) from None


def same_env(env: Any, other: Any) -> bool:
    """Whether two environments are one, wrappers aside: the same unwrapped object (an evaluation on either resets
    both)."""
    return getattr(env, "unwrapped", env) is getattr(other, "unwrapped", other)


def as_env(env: gym.Env | str, **make_args: Any) -> gym.Env:
    """``env`` itself, or the environment ``gymnasium.make(env, **make_args)`` makes of a registered id.

    The one place where avq makes an environment from an id: avq's own ids, any id registered by an installed
    package, and Gymnasium's ``"module:id"`` form (``"mymodule:user/Nav3D-v0"``), where importing ``module``
    registers the id; the module is imported from the working directory (as ``python -m`` does) or the
    Python path, unless the id is registered already in this process.

    Raises:
        ValueError: the id is unknown, its module cannot be imported (the message names the module and
            what to do), or ``make_args`` are not arguments of the environment.
        TypeError: ``env`` is neither an environment nor a string.
    """
    if not isinstance(env, str):
        if not isinstance(env, gym.Env):
            raise TypeError(f"env must be a gymnasium.Env or a registered id, not {type(env).__name__}")
        return env
    module, env_id = split_env_id(env)
    if module is not None:
        if not module or not env_id:
            raise ValueError(f"environment {env!r}: give MODULE:ID, as in 'mymodule:user/Nav3D-v0'")
        if env_id not in gym.registry:  # (registered already in this process: nothing to import)
            _import_registering_module(module, env_id)
    with _cwd_on_path():  # (an entry point "module:Class" is imported by gymnasium.make)
        try:
            made = gym.make(env_id, **make_args)
        except gym.error.Error as exc:
            hint = (
                f"; module {module!r} was imported but does not register it"
                if module is not None
                else "; if a module of yours registers it, give MODULE:ID (as in 'mymodule:" + env_id + "'), "
                "and avq imports the module from the working directory"
            )
            raise ValueError(f"unknown environment {env!r} ({exc}){hint}") from None
        except TypeError as exc:
            raise ValueError(f"bad env-kwargs for {env!r}: {exc}") from None
    if module is not None:
        _REGISTERED_BY[env_id] = module
    return made
