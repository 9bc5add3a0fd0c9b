"""Environments shipped with avq, registered with Gymnasium on import."""

from __future__ import annotations

import gymnasium as gym

from avq.envs.grid_maze import GridMaze
from avq.envs.layouts import MAPS, Layout, load_layout, parse_layout, random_layout
from avq.envs.robot_maze import RobotMaze

__all__ = ["GridMaze", "RobotMaze", "MAPS", "Layout", "load_layout", "parse_layout", "random_layout", "register_envs"]


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
