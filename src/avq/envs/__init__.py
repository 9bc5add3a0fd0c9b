"""Environments shipped with avq, registered with Gymnasium on import."""

from __future__ import annotations

import gymnasium as gym

from avq.envs.grid_maze import GridMaze
from avq.envs.layouts import MAPS, Layout, load_layout, parse_layout

__all__ = ["GridMaze", "MAPS", "Layout", "load_layout", "parse_layout", "register_envs"]


def register_envs() -> None:
    """Register ``avq/GridMaze-v0`` (idempotent)."""
    if "avq/GridMaze-v0" not in gym.registry:
        gym.register(
            id="avq/GridMaze-v0",
            entry_point="avq.envs.grid_maze:GridMaze",
            max_episode_steps=100,
        )


register_envs()
