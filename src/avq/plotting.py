"""Figures: the partition of a maze (the paper's Fig. 4), its animation as it learns, and learning curves.

Plotting reads results; it never trains. Matplotlib is used with the Agg backend
and imported only here.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from avq._io import atomic_write_bytes
from avq.agents.base import BaseAgent
from avq.figure_data import GreedyWalk, PartitionView, maze_squares, partition_view, sample_walks

__all__ = ["plot_partition", "plot_partitions", "animate_partition", "plot_learning_curves", "learning_curves_figure",
           "running_mean", "mean_ci95", "MIN_SEEDS_FOR_INTERVAL"]

_ARROWS = np.array([[0, -1], [1, 0], [0, 1], [-1, 0]], dtype=float)  # N E S W in (x, y)


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | os.PathLike) -> Path:
    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=path.suffix.lstrip(".") or "png", dpi=150, bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())
    return path


def running_mean(y: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Trailing mean over ``window`` trials, only where a whole window exists.

    Returns the trials ``window .. len(y)`` (counted from 1) and the mean of the
    ``window`` values ending at each; nothing is padded, so no point averages
    fewer trials than the others. With ``window`` 1 (or less) the values themselves.
    """
    y = np.asarray(y, dtype=float)
    window = max(1, min(int(window), len(y)))
    if len(y) == 0:
        return np.zeros(0, dtype=np.int64), y
    c = np.cumsum(np.insert(y, 0, 0.0))
    return np.arange(window, len(y) + 1), (c[window:] - c[:-window]) / window


def mean_ci95(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean over axis 0 and the half-width of its 95% t-interval."""
    rows = np.asarray(rows, dtype=float)
    mean = rows.mean(axis=0)
    n = rows.shape[0]
    if n < 2:
        return mean, np.zeros_like(mean)
    from scipy.special import stdtrit  # Student's t quantile; far lighter to import than scipy.stats

    half = stdtrit(n - 1, 0.975) * rows.std(axis=0, ddof=1) / np.sqrt(n)
    return mean, half


# -- the partition of a maze (Fig. 4) ------------------------------------------------------------

_GOAL_COLOUR = (0.80, 0.93, 0.80, 1.0)
_WALL_COLOUR = (0.2, 0.2, 0.2, 1.0)
_Y_DOWN = "y (grows downwards, as in the layout)"


def _palette(plt) -> np.ndarray:
    """60 distinct pastel colours (RGBA), so that arrows and numbers stay readable on them."""
    colours = np.concatenate([plt.get_cmap(name)(np.arange(20)) for name in ("tab20", "tab20b", "tab20c")])
    colours[:, :3] = 0.55 + 0.45 * colours[:, :3]
    return colours


def _cell_image(layout, view: PartitionView, colour_of_cell: np.ndarray) -> np.ndarray:
    """``(h, w, 4)`` RGBA: walls dark, each square in its cell's colour, the goal light green."""
    img = np.zeros((layout.height, layout.width, 4))
    img[layout.walls] = _WALL_COLOUR
    img[view.squares[:, 1], view.squares[:, 0]] = colour_of_cell[view.cells]
    gx, gy = layout.goal
    img[gy, gx] = _GOAL_COLOUR
    return img


def _borders(layout, view: PartitionView) -> list:
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


def _cell_arrows(view: PartitionView) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per anchor (:func:`avq.figure_data.cell_anchors`): the cell, the square ``(x, y)`` and the unit
    vector of the greedy action there."""
    cells, at = view.anchors[:, 0], view.anchors[:, 1]
    return cells, view.squares[at].astype(float), _ARROWS[view.actions[at]]


def _quiver(ax, anchors: np.ndarray, directions: np.ndarray, length: float, width: float):
    """Arrows from the centres of their squares, in data units, so that they scale with the maze."""
    return ax.quiver(anchors[:, 0], anchors[:, 1], directions[:, 0] * length, directions[:, 1] * length, angles="xy",
                     scale_units="xy", scale=1, units="xy", width=width, headwidth=3.2, headlength=3,
                     headaxislength=2.7, color="k", zorder=3)


def _maze_axes(ax, layout, image: np.ndarray, segments: list, fontsize: float | None):
    """The maze's squares in the colours of ``image`` (:func:`_cell_image`) and the cells' borders;
    integer ticks with ``fontsize``, none with None (faster to draw, for the animation). Returns the
    squares (recolour with ``set_facecolor(image.reshape(-1, 4))``) and the border collection."""
    from matplotlib.collections import LineCollection, PolyCollection

    h, w = layout.height, layout.width
    y, x = np.mgrid[0:h, 0:w]
    corners = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    squares = np.stack([x.ravel(), y.ravel()], axis=1)[:, None, :] + corners  # row-major, as image
    cells = ax.add_collection(PolyCollection(squares, facecolors=image.reshape(-1, 4), edgecolors="none"))
    borders = ax.add_collection(LineCollection(segments, colors="k", linewidths=1.2))
    gx, gy = layout.goal
    ax.plot(gx, gy, "*", color="darkgreen", ms=18 if fontsize else 14, mec="k", zorder=4)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    if fontsize is None:
        ax.set_axis_off()
        return cells, borders
    ax.set_xticks(range(w))
    ax.set_yticks(range(h))
    ax.tick_params(labelsize=fontsize)
    ax.set_xlabel("x")
    ax.set_ylabel(_Y_DOWN)
    return cells, borders


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
        ax.plot(xy[walk.loop_from:, 0], xy[walk.loop_from:, 1], "--", color=colour, lw=2.4, zorder=5)
    if walk.bump_action is not None:
        wall = xy[-1] + _ARROWS[walk.bump_action] * 0.5
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
    plt = _plt()
    layout = env.unwrapped.layout
    h, w = layout.height, layout.width
    maze = maze_squares(env)
    palette = _palette(plt)
    n = len(agents)
    fig, axes = plt.subplots(1, n, figsize=(max(5.0, w * 0.6) * n, max(4.0, h * 0.6) + 1.2), squeeze=False)
    for k, (agent, ax) in enumerate(zip(agents, axes[0])):
        view = partition_view(agent, maze)
        colours = palette[np.arange(max(view.n_cells, 1)) % len(palette)]
        _maze_axes(ax, layout, _cell_image(layout, view, colours), _borders(layout, view), fontsize=8)
        placed, anchors, directions = _cell_arrows(view)
        numbered = view.vectors is not None
        if view.vectors is not None:
            ax.plot(view.vectors[:, 0], view.vectors[:, 1], "o", color="k", ms=3, ls="none", zorder=4,
                    label="codebook vector")
            for c, (ax_x, ax_y) in zip(placed, anchors):  # the number in the square's upper left corner
                ax.text(ax_x - 0.27, ax_y - 0.25, str(c + 1), fontsize=9, fontweight="bold", color="navy",
                        ha="center", va="center", zorder=4)
        _quiver(ax, anchors, directions, length=0.45 if numbered else 0.4, width=0.07 if numbered else 0.05)
        ax.plot([], [], marker=r"$\rightarrow$", color="k", ls="none", ms=12,
                label="greedy action of the cell (number: the cell)" if numbered else "greedy action")
        for walk in sample_walks(agent, env):
            _draw_walk(ax, walk)
        ax.plot([], [], "s", color="grey", ms=9, mfc="none", mew=2, ls="none", label="start of a path")
        ax.plot([], [], "*", color="darkgreen", ms=12, mec="k", ls="none", label="goal")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=8, frameon=False)
        ax.set_title(titles[k] if titles else f"{view.n_cells} cells for {layout.n_states} states", fontsize=11)
    fig.tight_layout()
    out = _save(fig, path)
    plt.close(fig)
    return out


def plot_partition(agent: BaseAgent, env, path: str | os.PathLike, title: str | None = None) -> Path:
    """Draw one agent's partition of a maze (:func:`plot_partitions` with one panel)."""
    return plot_partitions([agent], env, path, titles=[title] if title else None)


def _colour_ids(views: Sequence[PartitionView]) -> list[np.ndarray]:
    """A colour number per cell and frame that follows a cell from frame to frame.

    A cell keeps its colour while its codebook vector is the mutual nearest of a vector of the
    frame before (merges renumber the cells, so the index alone would repaint half the maze);
    any other cell takes the next unused number. Without a codebook the cell index is the colour.
    """
    ids: list[np.ndarray] = []
    prev_vectors, prev_ids, next_id = None, None, 0
    for view in views:
        if view.vectors is None:
            ids.append(np.arange(view.n_cells))
            continue
        vec = view.vectors
        new = np.full(len(vec), -1)
        if prev_vectors is not None and prev_ids is not None and len(prev_vectors) and len(vec):
            d = ((vec[:, None, :] - prev_vectors[None, :, :]) ** 2).sum(axis=2)
            nearest_old, nearest_new = d.argmin(axis=1), d.argmin(axis=0)
            mutual = nearest_new[nearest_old] == np.arange(len(vec))
            new[mutual] = prev_ids[nearest_old[mutual]]
        for k in np.flatnonzero(new < 0):
            new[k] = next_id
            next_id += 1
        ids.append(new)
        prev_vectors, prev_ids = vec, new
    return ids


def _palette_image(frame):
    """An RGB frame as a palette image for the GIF: its 255 most frequent colours, exactly, and every
    other colour as the nearest of those (with a frame of flat cells, most pixels keep their colour;
    about twice as fast as Pillow's median cut, which shifts more of them). The 256th entry is left
    free: Pillow makes it transparent, for the pixels that a frame leaves as they were."""
    from PIL import Image

    counts = frame.getcolors(1 << 16)
    if counts is None:  # (far more colours than a partition has)
        return frame.convert("P", palette=Image.Palette.ADAPTIVE)
    n = np.fromiter((c for c, _ in counts), np.int64, len(counts))
    colours = np.array([c for _, c in counts], dtype=np.int64).reshape(-1, 3)
    key = (colours[:, 0] << 16) | (colours[:, 1] << 8) | colours[:, 2]
    order = np.lexsort((key, -n))  # the most frequent first (then by colour)
    kept, others = order[:255], order[255:]
    palette = colours[kept]
    entry = np.empty(len(colours), dtype=np.uint8)  # each colour's palette entry: itself, or its nearest
    entry[kept] = np.arange(len(kept))
    if len(others):
        d = sum((colours[others, k, None] - palette[None, :, k]) ** 2 for k in range(3))
        entry[others] = d.argmin(axis=1)  # (squared distance in RGB; the first entry on a tie)
    rgb = np.asarray(frame)
    pixels = (rgb[..., 0].astype(np.int64) << 16) | (rgb[..., 1].astype(np.int64) << 8) | rgb[..., 2]
    by_key = np.argsort(key)
    image = Image.fromarray(entry[by_key[np.searchsorted(key[by_key], pixels)]], "P")
    image.putpalette(palette.astype(np.uint8).ravel().tolist())
    return image


def animate_partition(
    views: Sequence[PartitionView],
    env,
    path: str | os.PathLike,
    title: str | None = None,
    fps: int = 8,
    dpi: int = 90,
) -> Path:
    """An animated GIF of the partition as it learns: one frame per view (of a :class:`PartitionRecorder`).

    Each frame: the cells' colours and borders, each cell's greedy action on its own square, the
    codebook vectors, and the trial (episode) number and the number of cells. A cell keeps its
    colour from frame to frame while its vector stays. Each frame is drawn by Matplotlib (Agg) and
    written with Pillow, in its own palette of its 255 most frequent colours.
    """
    if not views:
        raise ValueError("no views to animate: record at least one episode")
    plt = _plt()
    from PIL import Image

    layout = env.unwrapped.layout
    h, w = layout.height, layout.width
    palette = _palette(plt)
    ids = _colour_ids(views)
    fig, ax = plt.subplots(figsize=(max(4.0, w * 0.45), max(3.5, h * 0.45) + 0.5))
    cells, borders = _maze_axes(ax, layout, _cell_image(layout, views[0], palette[ids[0] % len(palette)]),
                                _borders(layout, views[0]), fontsize=None)
    dots, = ax.plot([], [], "o", color="k", ms=2.5, ls="none", zorder=4)

    def heading(view: PartitionView) -> str:
        what = f"trial {view.episode}: {view.n_cells} cell{'s' if view.n_cells != 1 else ''}"
        return f"{title}\n{what}" if title else what

    # y=1.0 is where Matplotlib places it over axes without ticks; given, it is not worked out again for
    # every frame (which measures the hidden tick labels).
    text = ax.set_title(heading(views[0]), fontsize=11, y=1.0)
    # Room for a two-line title; no layout engine, which would lay the figure out again for every frame.
    fig.subplots_adjust(left=0.02, right=0.98, bottom=0.02, top=1 - 0.55 / fig.get_figheight())
    width, height = fig.get_size_inches()
    size = (int(width * dpi), int(height * dpi))
    frames = []
    arrows = None
    for view, colour_ids in zip(views, ids):
        cells.set_facecolor(_cell_image(layout, view, palette[colour_ids % len(palette)]).reshape(-1, 4))
        borders.set_segments(_borders(layout, view))
        if view.vectors is not None:
            dots.set_data(view.vectors[:, 0], view.vectors[:, 1])
        if arrows is not None:
            arrows.remove()
        _, anchors, directions = _cell_arrows(view)
        arrows = _quiver(ax, anchors, directions, length=0.45, width=0.09)
        text.set_text(heading(view))
        buf = io.BytesIO()
        fig.savefig(buf, format="rgba", dpi=dpi)
        # (Pillow's annotation leaves out memoryview, which frombuffer reads without a copy)
        frame = Image.frombuffer("RGBA", size, buf.getbuffer(), "raw", "RGBA", 0, 1).convert("RGB")  # type: ignore[arg-type]
        frames.append(_palette_image(frame))
    plt.close(fig)
    gif = io.BytesIO()
    frames[0].save(gif, format="GIF", save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)
    out = Path(path)
    atomic_write_bytes(out, gif.getvalue())
    return out


# -- learning curves -------------------------------------------------------------------------------


#: With fewer seeds than this, the spread over seeds is drawn as the seeds themselves (thin lines):
#: a t-interval from two or three seeds is as wide as the axis and says little.
MIN_SEEDS_FOR_INTERVAL = 5


def _mean_and_spread(ax, x: np.ndarray, rows: np.ndarray, colour: str, band: bool, label: str) -> None:
    """The mean over seeds (rows), and either its 95% t-interval as a band or every seed as a thin line."""
    mean, half = mean_ci95(rows)
    if band:
        ax.fill_between(x, mean - half, mean + half, color=colour, alpha=0.2, lw=0)
    else:
        for row in rows:
            ax.plot(x, row, color=colour, lw=0.7, alpha=0.4)
    ax.plot(x, mean, color=colour, lw=1.8, label=label)


def learning_curves_figure(
    curves: Mapping[str, Sequence[np.ndarray]],
    cells: Mapping[str, Sequence[np.ndarray]] | None = None,
    window: int = 20,
    ylabel: str = "steps per trial",
    title: str | None = None,
    xlabel: str = "trial",
):
    """The figure of :func:`plot_learning_curves` (a Matplotlib ``Figure``; the caller closes it)."""
    plt = _plt()
    from matplotlib.ticker import MaxNLocator

    two = bool(cells)
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(11 if two else 6.5, 4.2), squeeze=False)
    ax = axes[0, 0]
    band = min(len(runs) for runs in curves.values()) >= MIN_SEEDS_FOR_INTERVAL
    shortest = min(len(r) for runs in curves.values() for r in runs)
    window = max(1, min(int(window), shortest // 10))
    colour = {name: f"C{k % 10}" for k, name in enumerate(curves)}
    for name, runs in curves.items():
        n = min(len(r) for r in runs)
        means = [running_mean(np.asarray(r[:n], float), window) for r in runs]
        label = f"{name} ({len(runs)} seed{'s' if len(runs) != 1 else ''})"
        _mean_and_spread(ax, means[0][0], np.stack([m for _, m in means]), colour[name], band, label)
    spread = ("mean over seeds and its 95% t-interval" if band else
              "mean over seeds (thick) and each seed (thin)")
    smoothing = f", each a {window}-{xlabel} trailing mean" if window > 1 else ""
    ax.set_title(f"{title or 'learning curves'}\n({spread}{smoothing})", fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if cells:  # (two)
        ax2 = axes[0, 1]
        for name, runs in cells.items():
            n = min(len(r) for r in runs)
            rows = np.stack([np.asarray(r[:n], float) for r in runs])
            _mean_and_spread(ax2, np.arange(1, n + 1), rows, colour.get(name, "k"), band, name)
        left_out = [name for name in curves if name not in cells]
        note = f"\n(not drawn: {', '.join(left_out)}, without a codebook)" if left_out else ""
        ax2.set_title(f"codebook size{note}", fontsize=10)
        ax2.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax2.set_xlabel(xlabel)
        ax2.set_ylabel("cells")
    for a in axes[0]:
        a.set_xlim(left=0)  # the panels share the trial axis, though a trailing mean starts later
        a.xaxis.set_major_locator(MaxNLocator(integer=True))
        a.grid(alpha=0.3)
    fig.tight_layout()
    # One legend for both panels (an agent has the same colour in each), below them, off the data.
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=min(3, len(labels)),
               fontsize=8, frameon=False)
    return fig


def plot_learning_curves(
    curves: Mapping[str, Sequence[np.ndarray]],
    path: str | os.PathLike,
    cells: Mapping[str, Sequence[np.ndarray]] | None = None,
    window: int = 20,
    ylabel: str = "steps per trial",
    title: str | None = None,
    xlabel: str = "trial",
) -> Path:
    """Learning curves, one line per agent (or configuration): the mean over seeds and its spread.

    The spread is the 95% t-interval of the mean with at least :data:`MIN_SEEDS_FOR_INTERVAL`
    seeds for every curve, else each seed as a thin line. Curves are trailing means over
    ``window`` trials (:func:`running_mean`; at most a tenth of the shortest run), drawn from
    the first whole window. The legend goes below the panels.

    Args:
        curves: agent -> one array per seed (e.g. steps per trial).
        path: File to write.
        cells: agent -> one array per seed of codebook size per trial (a second panel,
            which names the agents of ``curves`` it leaves out).
        window: Trailing-mean window.
        title: First line of the title; the second says what is drawn.
    """
    fig = learning_curves_figure(curves, cells=cells, window=window, ylabel=ylabel, title=title, xlabel=xlabel)
    out = _save(fig, path)
    _plt().close(fig)
    return out
