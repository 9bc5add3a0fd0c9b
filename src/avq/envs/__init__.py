"""Environments shipped with avq, registered with Gymnasium on import."""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from avq.envs.grid_maze import GridMaze
from avq.envs.layouts import MAPS, Layout, load_layout, parse_layout, random_layout, refine_layout
from avq.envs.robot_maze import RobotMaze

__all__ = [
    "as_env",
    "GridMaze",
    "RobotMaze",
    "MAPS",
    "Layout",
    "load_layout",
    "parse_layout",
    "random_layout",
    "refine_layout",
    "register_envs",
]


def register_envs() -> None:
    """Register ``avq/GridMaze-v0`` and ``avq/RobotMaze-v0`` (idempotent).

    RobotMaze is registered without ``max_episode_steps``: it truncates by itself
    after ``max_steps`` steps, a limit that scales with its ``move`` argument.
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


register_envs()


def as_env(env: gym.Env | str, **make_args: Any) -> gym.Env:
    """``env`` itself, or the environment ``gymnasium.make(env, **make_args)`` makes of a registered id
    (avq's own ids included); a ``ValueError`` naming the id when it cannot be made."""
    if isinstance(env, str):
        try:
            return gym.make(env, **make_args)
        except (gym.error.Error, TypeError) as exc:
            raise ValueError(f"cannot make environment {env!r}: {exc}") from None
    if not isinstance(env, gym.Env):
        raise TypeError(f"env must be a gymnasium.Env or a registered id, not {type(env).__name__}")
    return env
