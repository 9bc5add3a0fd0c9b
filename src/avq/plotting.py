"""Figures: the partition of a maze (the paper's Fig. 4) and learning curves.

Plotting reads results; it never trains. Matplotlib is used with the Agg backend
and imported only here.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from avq._io import atomic_write_bytes
from avq.agents.base import BaseAgent

__all__ = ["plot_partition", "plot_learning_curves", "smooth", "mean_ci95"]

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


def smooth(y: np.ndarray, window: int) -> np.ndarray:
    """Trailing moving average (the first points average what exists so far)."""
    y = np.asarray(y, dtype=float)
    if window <= 1 or len(y) == 0:
        return y
    c = np.cumsum(np.insert(y, 0, 0.0))
    idx = np.arange(1, len(y) + 1)
    lo = np.maximum(idx - window, 0)
    return (c[idx] - c[lo]) / (idx - lo)


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


def greedy_path(agent: BaseAgent, env, start: tuple[int, int], max_steps: int = 100) -> list[tuple[int, int]]:
    """Positions visited by the greedy policy from ``start`` on a grid maze."""
    base = env.unwrapped
    obs, _ = base.reset(options={"start": start})
    path = [start]
    for _ in range(max_steps):
        action, _ = agent.predict(obs, deterministic=True)
        obs, _, terminated, _, _ = base.step(action)
        path.append((int(obs[0]), int(obs[1])))
        if terminated:
            break
    return path


def plot_partition(agent: BaseAgent, env, path: str | os.PathLike, title: str | None = None) -> Path:
    """Draw the maze's partition into cells with each cell's greedy action (Fig. 4).

    Walls; every free position coloured by its cell; codebook vectors marked and
    numbered; the greedy action of each cell as an arrow from its vector; one greedy
    path from the layout's start (or the free position farthest from the goal) to
    the goal. For an agent without a codebook each position is its own cell.
    """
    plt = _plt()
    from matplotlib.colors import ListedColormap

    layout = env.unwrapped.layout
    h, w = layout.height, layout.width
    free = layout.free_positions(include_goal=True)
    has_codebook = hasattr(agent, "codebook_")
    if has_codebook:
        vectors = agent.codebook_
        cells = agent.cells(free.astype(float))
        q = agent.q_
    else:
        vectors = free.astype(float)
        cells = np.arange(len(free))
        q = None
    grid = np.full((h, w), np.nan)
    grid[free[:, 1], free[:, 0]] = cells
    n_cells = len(vectors)
    base_colours = np.concatenate([plt.get_cmap(name)(np.arange(20)) for name in ("tab20", "tab20b", "tab20c")])
    base_colours[:, :3] = 0.55 + 0.45 * base_colours[:, :3]  # pastel, so arrows and numbers stay readable
    cmap = ListedColormap(base_colours[np.arange(max(n_cells, 1)) % len(base_colours)])
    fig, ax = plt.subplots(figsize=(max(5, w * 0.5), max(4, h * 0.5)))
    ax.imshow(np.where(layout.walls, 1.0, np.nan), cmap=ListedColormap([(0.2, 0.2, 0.2)]), vmin=0, vmax=1,
              origin="upper", extent=(-0.5, w - 0.5, h - 0.5, -0.5))
    ax.imshow(grid, cmap=cmap, vmin=-0.5, vmax=max(n_cells, 1) - 0.5, origin="upper",
              extent=(-0.5, w - 0.5, h - 0.5, -0.5), interpolation="nearest")
    # Cell borders: segments between neighbouring free positions of different cells, drawn as one collection.
    from matplotlib.collections import LineCollection

    right = ~np.isnan(grid[:, :-1]) & ~np.isnan(grid[:, 1:]) & (grid[:, :-1] != grid[:, 1:])
    below = ~np.isnan(grid[:-1, :]) & ~np.isnan(grid[1:, :]) & (grid[:-1, :] != grid[1:, :])
    ry, rx = np.nonzero(right)
    by, bx = np.nonzero(below)
    segments = [((x + 0.5, y - 0.5), (x + 0.5, y + 0.5)) for y, x in zip(ry, rx)]
    segments += [((x - 0.5, y + 0.5), (x + 0.5, y + 0.5)) for y, x in zip(by, bx)]
    ax.add_collection(LineCollection(segments, colors="k", linewidths=1.2))
    if has_codebook:
        origins = np.asarray(vectors, dtype=float)
        arrows = _ARROWS[q.argmax(axis=1)] * 0.45
        ax.plot(origins[:, 0], origins[:, 1], "o", color="k", ms=3, ls="none")
        for k, (vx, vy) in enumerate(origins):
            ax.text(vx + 0.12, vy - 0.18, str(k + 1), fontsize=7, color="navy")
        width = 0.006
    else:
        origins = free.astype(float)
        actions, _ = agent.predict(origins, deterministic=True)
        arrows = _ARROWS[np.atleast_1d(actions)] * 0.35
        width = 0.004
    # One quiver for every arrow; y grows downwards on the maze, as in the data.
    ax.quiver(origins[:, 0], origins[:, 1], arrows[:, 0], arrows[:, 1], angles="xy", scale_units="xy", scale=1,
              width=width, headwidth=4, headlength=5, color="k", zorder=3)
    gx, gy = layout.goal
    ax.plot(gx, gy, "*", color="darkgreen", ms=16, mec="k")
    start = layout.start
    if start is None:
        starts = layout.free_positions(include_goal=False)
        far = np.argmax(layout.distances[starts[:, 1], starts[:, 0]])
        start = (int(starts[far, 0]), int(starts[far, 1]))
    path_xy = np.array(greedy_path(agent, env, start))
    reached = tuple(path_xy[-1]) == tuple(layout.goal)
    ax.plot(path_xy[:, 0], path_xy[:, 1], "-", color="crimson", lw=2.2, alpha=0.85,
            label="greedy path" + ("" if reached else " (does not reach the goal)"))
    ax.plot(*start, "s", color="crimson", ms=8, mfc="none", mew=2, label="start")
    ax.plot([], [], "*", color="darkgreen", ms=12, mec="k", label="goal")
    if has_codebook:
        ax.plot([], [], "o", color="k", ms=3, label="codebook vector (cell number)")
        ax.plot([], [], marker=r"$\rightarrow$", color="k", ls="none", ms=10, label="greedy action of the cell")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3, fontsize=7, frameon=False)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.set_xticks(range(w))
    ax.set_yticks(range(h))
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(title or f"{n_cells} cells for {layout.n_states} states")
    out = _save(fig, path)
    plt.close(fig)
    return out


def plot_learning_curves(
    curves: Mapping[str, Sequence[np.ndarray]],
    path: str | os.PathLike,
    cells: Mapping[str, Sequence[np.ndarray]] | None = None,
    window: int = 20,
    ylabel: str = "steps per trial",
    title: str | None = None,
    xlabel: str = "trial",
) -> Path:
    """Smoothed mean and 95% interval over seeds, one line per agent.

    Args:
        curves: agent -> one array per seed (e.g. steps per trial).
        path: File to write.
        cells: agent -> one array per seed of codebook size per trial (second panel).
        window: Moving-average window.
    """
    plt = _plt()
    two = bool(cells)
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(11 if two else 6, 4), squeeze=False)
    ax = axes[0, 0]
    for name, runs in curves.items():
        n = min(len(r) for r in runs)
        rows = np.stack([smooth(np.asarray(r[:n], float), window) for r in runs])
        mean, half = mean_ci95(rows)
        x = np.arange(1, n + 1)
        ax.plot(x, mean, label=f"{name} ({len(runs)} seed{'s' if len(runs) != 1 else ''})")
        ax.fill_between(x, mean - half, mean + half, alpha=0.25)
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"{ylabel} ({min(window, n)}-trial mean)")
    ax.set_title(title or "learning curves (mean and 95% t-interval over seeds)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    if two:
        ax2 = axes[0, 1]
        for name, runs in cells.items():
            n = min(len(r) for r in runs)
            rows = np.stack([np.asarray(r[:n], float) for r in runs])
            mean, half = mean_ci95(rows)
            x = np.arange(1, n + 1)
            ax2.plot(x, mean, label=name)
            ax2.fill_between(x, mean - half, mean + half, alpha=0.25)
        ax2.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax2.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax2.set_xlabel(xlabel)
        ax2.set_ylabel("cells")
        ax2.set_title("codebook size")
        ax2.legend(fontsize=8)
        ax2.grid(alpha=0.3)
    out = _save(fig, path)
    plt.close(fig)
    return out
