"""Pictures of the mazes with their robot: the ``rgb_array`` frames of GridMaze and RobotMaze.

Both mazes draw the layout the same way (:func:`avq.envs.layouts.layout_image`: walls dark, free
squares light, the goal green; and :func:`~avq.envs.layouts.layout_text` for ``ansi``) and then
their robot on top, which is where they differ: GridMaze's robot is a disc inside its square,
RobotMaze's a disc of its own radius at its continuous position, with its sonar beams. This
module holds those drawings, so that the env modules hold the dynamics and the renderer is
found in one place.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from avq.envs.layouts import COLOURS, Layout, layout_image

__all__ = ["grid_frame", "robot_frame", "FRAME_COLOURS", "MazeRendering"]

#: Colours of the frames (RGB): the layout's :data:`~avq.envs.layouts.COLOURS` and the sonar beams.
FRAME_COLOURS = {**COLOURS, "beam": (240, 170, 20)}


def grid_frame(layout: Layout, position: tuple[int, int], cell: int = 16) -> np.ndarray:
    """GridMaze's frame: the layout, ``cell`` pixels a square, and the robot a disc in its square.

    Args:
        layout: The maze's layout.
        position: The robot's square ``(x, y)``.
        cell: Pixels per square.

    Returns:
        ``(H * cell, W * cell, 3)`` uint8 RGB.
    """
    img = layout_image(layout, cell)
    # The robot: a disc in its cell.
    x, y = position
    yy, xx = np.mgrid[0:cell, 0:cell]
    r = cell / 2 - 0.5
    disc = (xx - r) ** 2 + (yy - r) ** 2 <= (0.75 * r) ** 2
    block = img[y * cell : (y + 1) * cell, x * cell : (x + 1) * cell]
    block[disc] = FRAME_COLOURS["robot"]
    return img


def robot_frame(
    layout: Layout, x: float, y: float, radius: float, directions: np.ndarray, ranges: np.ndarray, scale: int = 32
) -> np.ndarray:
    """RobotMaze's frame: walls dark, goal green, the robot a red disc, each beam a line from its surface to its range.

    Args:
        layout: The maze's layout.
        x, y: The robot's centre, world coordinates.
        radius: The robot's radius.
        directions: ``(16, 2)`` unit vectors of the beams
            (:func:`~avq.envs.robot_geometry.sonar_directions`).
        ranges: The beams' ranges; a beam of range 0 is not drawn.
        scale: Pixels per square.

    Returns:
        ``(H * scale, W * scale, 3)`` uint8 RGB.
    """
    img = layout_image(layout, scale)
    hp, wp = img.shape[:2]

    def to_px(v: np.ndarray) -> np.ndarray:  # world coordinate -> pixel index
        return np.floor((v + 0.5) * scale).astype(np.int64)

    for (dx, dy), rng in zip(directions, ranges):
        if rng <= 0.0:
            continue
        s = np.linspace(radius, radius + rng, math.ceil(2 * rng * scale) + 2)
        cols = np.clip(to_px(x + s * dx), 0, wp - 1)
        rows = np.clip(to_px(y + s * dy), 0, hp - 1)
        img[rows, cols] = FRAME_COLOURS["beam"]
    # The robot: pixels whose centre lies within radius of the robot's centre.
    yy, xx = np.mgrid[0:hp, 0:wp]
    px = (xx + 0.5) / scale - 0.5
    py = (yy + 0.5) / scale - 0.5
    img[(px - x) ** 2 + (py - y) ** 2 <= radius**2] = FRAME_COLOURS["robot"]
    return img


class MazeRendering:
    """What both maze environments share about rendering: the modes, the check of ``render_mode``, and
    :meth:`render`, which draws the env's own ``_render_text`` or ``_render_rgb``."""

    #: The render modes (each maze adds its ``render_fps``).
    RENDER_MODES = ["ansi", "rgb_array"]
    render_mode: str | None

    def _set_render_mode(self, render_mode: Any) -> None:
        if render_mode is not None and render_mode not in self.RENDER_MODES:
            raise ValueError(f"render_mode must be one of {self.RENDER_MODES}, not {render_mode!r}")
        self.render_mode = render_mode

    def render(self) -> str | np.ndarray | None:
        """The maze and the robot: text with ``render_mode="ansi"``, an RGB array with ``"rgb_array"``, else None."""
        if self.render_mode == "ansi":
            return self._render_text()
        if self.render_mode == "rgb_array":
            return self._render_rgb()
        return None

    def _render_text(self) -> str:
        raise NotImplementedError

    def _render_rgb(self) -> np.ndarray:
        raise NotImplementedError
