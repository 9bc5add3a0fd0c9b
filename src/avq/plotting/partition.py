"""The partition of a maze (the paper's Fig. 4): each cell a colour, its greedy action an arrow, with greedy
walks from chosen starts; and the drawing helpers that the animation shares."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from avq.agents.base import BaseAgent
from avq.figure_data import GreedyWalk, PartitionView, maze_squares, partition_view, sample_walks
from avq.plotting._figure import pyplot, save_figure

__all__ = [
    "plot_partition",
    "plot_partitions",
    "cell_palette",
    "cell_image",
    "cell_borders",
    "cell_arrows",
    "draw_arrows",
    "maze_axes",
    "ARROWS",
    "Y_DOWN",
]


ARROWS = np.array([[0, -1], [1, 0], [0, 1], [-1, 0]], dtype=float)  # N E S W in (x, y)
_GOAL_COLOUR = (0.80, 0.93, 0.80, 1.0)
_WALL_COLOUR = (0.2, 0.2, 0.2, 1.0)
Y_DOWN = "y (grows downwards, as in the layout)"


def cell_palette(plt) -> np.ndarray:
    """60 distinct pastel colours (RGBA), so that arrows and numbers stay readable on them."""
    colours = np.concatenate([plt.get_cmap(name)(np.arange(20)) for name in ("tab20", "tab20b", "tab20c")])
    colours[:, :3] = 0.55 + 0.45 * colours[:, :3]
    return colours


def cell_image(layout, view: PartitionView, colour_of_cell: np.ndarray) -> np.ndarray:
    """``(h, w, 4)`` RGBA: walls dark, each square in its cell's colour, the goal light green."""
    img = np.zeros((layout.height, layout.width, 4))
    img[layout.walls] = _WALL_COLOUR
    img[view.squares[:, 1], view.squares[:, 0]] = colour_of_cell[view.cells]
    gx, gy = layout.goal
    img[gy, gx] = _GOAL_COLOUR
    return img


def cell_borders(layout, view: PartitionView) -> list:
    """Segments between neighbouring squares of different cells (the goal counts as a cell of its own)."""
    grid = np.full((layout.height, layout.width), np.nan)
    grid[view.squares[:, 1], view.squares[:, 0]] = view.cells
    gx, gy = layout.goal
    grid[gy, gx] = -1
    right = ~np.isnan(grid[:, :-1]) & ~np.isnan(grid[:, 1:]) & (grid[:, :-1] != grid[:, 1:])
    below = ~np.isnan(grid[:-1, :]) & ~np.isnan(grid[1:, :]) & (grid[:-1, :] != grid[1:, :])
    ry, rx = np.nonzero(right)
    by, bx = np.nonzero(below)
    segments = [((x + 0.5, y - 0.5), (x + 0.5, y + 0.5)) for y, x in zip(ry, rx)]
    segments += [((x - 0.5, y + 0.5), (x + 0.5, y + 0.5)) for y, x in zip(by, bx)]
    return segments


def cell_arrows(view: PartitionView) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per anchor (:func:`avq.figure_data.cell_anchors`): the cell, the square ``(x, y)`` and the unit
    vector of the greedy action there."""
    cells, at = view.anchors[:, 0], view.anchors[:, 1]
    return cells, view.squares[at].astype(float), ARROWS[view.actions[at]]


#: The arrows' heads, in widths of their shafts (Matplotlib's quiver).
_HEAD = {"headwidth": 3.2, "headlength": 3.0, "headaxislength": 2.7}


def draw_arrows(ax, anchors: np.ndarray, directions: np.ndarray, length: float, width: float):
    """Arrows from the centres of their squares, in data units, so that they scale with the maze."""
    return ax.quiver(
        anchors[:, 0],
        anchors[:, 1],
        directions[:, 0] * length,
        directions[:, 1] * length,
        angles="xy",
        scale_units="xy",
        scale=1,
        units="xy",
        width=width,
        **_HEAD,
        color="k",
        zorder=3,
    )


def _arrow_marker(length: float, width: float) -> np.ndarray:
    """The outline of an arrow of :func:`draw_arrows`, pointing right, as a marker (vertices about (0, 0)):
    the legend's sample of the arrows drawn. (A marker of its own: the glyph ``$\\rightarrow$`` would
    cost the figure Matplotlib's mathtext parser, about a tenth of a second to build.)"""
    n = length / width  # (in widths of the shaft, as quiver's outline)
    head, axis, half = _HEAD["headlength"], _HEAD["headaxislength"], _HEAD["headwidth"] / 2
    outline = [(0, 0.5), (n - axis, 0.5), (n - head, half), (n, 0), (n - head, -half), (n - axis, -0.5), (0, -0.5)]
    return np.array(outline) - [n / 2, 0]


def maze_axes(ax, layout, image: np.ndarray, segments: list, fontsize: float | None):
    """The maze's squares in the colours of ``image`` (:func:`cell_image`), the cells' borders and the goal;
    integer ticks with ``fontsize``, none with None (faster to draw, for the animation). Returns the
    squares (recolour with ``set_facecolor(image.reshape(-1, 4))``), the border collection and the goal's
    marker."""
    from matplotlib.collections import LineCollection, PolyCollection

    h, w = layout.height, layout.width
    y, x = np.mgrid[0:h, 0:w]
    corners = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    squares = np.stack([x.ravel(), y.ravel()], axis=1)[:, None, :] + corners  # row-major, as image
    cells = ax.add_collection(PolyCollection(squares, facecolors=image.reshape(-1, 4), edgecolors="none"))
    borders = ax.add_collection(LineCollection(segments, colors="k", linewidths=1.2))
    gx, gy = layout.goal
    (goal,) = ax.plot(gx, gy, "*", color="darkgreen", ms=18 if fontsize else 14, mec="k", zorder=4)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    if fontsize is None:
        ax.set_axis_off()
        return cells, borders, goal
    ax.set_xticks(range(w))
    ax.set_yticks(range(h))
    ax.tick_params(labelsize=fontsize)
    ax.set_xlabel("x")
    ax.set_ylabel(Y_DOWN)
    return cells, borders, goal


def _walk_label(walk: GreedyWalk) -> str:
    x, y = (int(v) if float(v).is_integer() else float(v) for v in walk.positions[0])
    where = f"greedy path from ({x}, {y})"
    if walk.outcome == "goal":
        return f"{where}: reaches the goal in {walk.steps} steps"
    if walk.outcome == "bump":
        return f"{where}: runs into a wall at step {walk.steps}, and again for ever (x)"
    if walk.outcome == "loop" and walk.loop_from is not None:  # (greedy_walk gives a loop's start)
        return f"{where}: goes round a loop of {len(walk.positions) - 1 - walk.loop_from} squares for ever (dashed)"
    return f"{where}: not at the goal after {walk.steps} steps"


def _draw_walk(ax, walk: GreedyWalk) -> None:
    """A greedy path from its start (square): blue to the goal; red otherwise, with a bump as a
    stroke into the wall ending in a cross, and a loop dashed."""
    colour = "mediumblue" if walk.outcome == "goal" else "crimson"
    xy = walk.positions.astype(float)
    end = len(xy) if walk.loop_from is None else walk.loop_from + 1
    ax.plot(xy[:end, 0], xy[:end, 1], "-", color=colour, lw=2.4, alpha=0.85, zorder=5, label=_walk_label(walk))
    if walk.loop_from is not None:
        ax.plot(xy[walk.loop_from :, 0], xy[walk.loop_from :, 1], "--", color=colour, lw=2.4, zorder=5)
    if walk.bump_action is not None:
        wall = xy[-1] + ARROWS[walk.bump_action] * 0.5
        ax.plot([xy[-1, 0], wall[0]], [xy[-1, 1], wall[1]], "-", color=colour, lw=3, zorder=5)
        ax.plot(*wall, "X", color=colour, ms=13, mec="white", mew=1, zorder=6)
    ax.plot(*xy[0], "s", color=colour, ms=11, mfc="none", mew=2.2, zorder=6)


def plot_partitions(
    agents: Sequence[BaseAgent],
    env,
    path: str | os.PathLike,
    titles: Sequence[str] | None = None,
) -> Path:
    """Draw the partition of a maze of one or more agents side by side (the paper's Fig. 4).

    Each panel: walls; every free square coloured by its cell (the cell of the observation at
    its centre); each cell's number and the arrow of its greedy action on one of its own squares
    (:func:`avq.figure_data.cell_anchors`); the codebook vectors as dots; and greedy paths
    (:func:`avq.figure_data.sample_walks`): from the farthest start that reaches the goal, and
    from the farthest that does not, drawn to the wall it runs into or round the loop it never
    leaves (:func:`avq.figure_data.greedy_walk`).
    For an agent without cells each square is its own cell. ``env`` is reset many times: give
    one that is not being trained on.
    """
    plt = pyplot()
    layout = env.unwrapped.layout
    h, w = layout.height, layout.width
    maze = maze_squares(env)
    palette = cell_palette(plt)
    n = len(agents)
    fig, axes = plt.subplots(1, n, figsize=(max(5.0, w * 0.6) * n, max(4.0, h * 0.6) + 1.2), squeeze=False)
    for k, (agent, ax) in enumerate(zip(agents, axes[0])):
        view = partition_view(agent, maze)
        colours = palette[np.arange(max(view.n_cells, 1)) % len(palette)]
        maze_axes(ax, layout, cell_image(layout, view, colours), cell_borders(layout, view), fontsize=8)
        placed, anchors, directions = cell_arrows(view)
        numbered = view.vectors is not None
        if view.vectors is not None:
            ax.plot(
                view.vectors[:, 0],
                view.vectors[:, 1],
                "o",
                color="k",
                ms=3,
                ls="none",
                zorder=4,
                label="codebook vector",
            )
            for c, (ax_x, ax_y) in zip(placed, anchors):  # the number in the square's upper left corner
                ax.text(
                    ax_x - 0.27,
                    ax_y - 0.25,
                    str(c + 1),
                    fontsize=9,
                    fontweight="bold",
                    color="navy",
                    ha="center",
                    va="center",
                    zorder=4,
                    in_layout=False,  # (inside the maze: the layout and the crop need not measure them)
                )
        length, width = (0.45, 0.07) if numbered else (0.4, 0.05)
        draw_arrows(ax, anchors, directions, length=length, width=width)
        ax.plot(
            [],
            [],
            marker=_arrow_marker(length, width),
            color="k",
            ls="none",
            ms=12,
            label="greedy action of the cell (number: the cell)" if numbered else "greedy action",
        )
        for walk in sample_walks(agent, env):
            _draw_walk(ax, walk)
        ax.plot([], [], "s", color="grey", ms=9, mfc="none", mew=2, ls="none", label="start of a path")
        ax.plot([], [], "*", color="darkgreen", ms=12, mec="k", ls="none", label="goal")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=8, frameon=False)
        ax.set_title(titles[k] if titles else f"{view.n_cells} cells for {layout.n_states} states", fontsize=11)
    fig.tight_layout()
    out = save_figure(fig, path)
    plt.close(fig)
    return out


def plot_partition(agent: BaseAgent, env, path: str | os.PathLike, title: str | None = None) -> Path:
    """Draw one agent's partition of a maze (:func:`plot_partitions` with one panel)."""
    return plot_partitions([agent], env, path, titles=[title] if title else None)
