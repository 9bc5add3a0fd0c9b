"""Learning curves: the return per episode as a running mean, with the spread over seeds; seeds that never
learned drawn apart (:func:`never_learned`)."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from avq.plotting._figure import pyplot, save_figure

__all__ = [
    "plot_learning_curves",
    "learning_curves_figure",
    "never_learned",
    "running_mean",
    "mean_ci95",
    "MIN_SEEDS_FOR_INTERVAL",
]


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


#: With fewer seeds than this, the spread over seeds is drawn as the seeds themselves (thin lines):
#: a t-interval from two or three seeds is as wide as the axis and says little.
MIN_SEEDS_FOR_INTERVAL = 5


def never_learned(
    runs: Sequence[np.ndarray], higher_is_better: bool = False, success: float | None = None
) -> np.ndarray:
    """Which seeds (runs of one line, each a value per episode) never learned.

    Over the episodes all runs have, each cut into tenths: a seed never learned when the mean of its last
    tenth is not better than the mean of its first tenth by more than both a tenth of the line's spread
    (the largest minus the smallest mean of a tenth over all its seeds) and twice the standard error of
    that difference. Where a success level is given (``success``), a seed never learned when the mean of
    its last tenth does not reach it. Runs shorter than 2 episodes are not judged (False).

    Returns:
        ``(len(runs),)`` bool.
    """
    n = min((len(r) for r in runs), default=0)
    if n < 2:
        return np.zeros(len(runs), dtype=bool)
    sign = 1.0 if higher_is_better else -1.0
    rows = sign * np.stack([np.asarray(r[:n], dtype=float) for r in runs])
    tenth = max(1, n // 10)
    first, last = rows[:, :tenth], rows[:, n - tenth :]
    if success is not None:
        return last.mean(axis=1) < sign * float(success)
    tenths = np.stack([rows[:, k * tenth : (k + 1) * tenth].mean(axis=1) for k in range(n // tenth)], axis=1)
    spread = float(tenths.max() - tenths.min())
    error = np.sqrt((first.var(axis=1, ddof=1) + last.var(axis=1, ddof=1)) / tenth) if tenth > 1 else 0.0
    return last.mean(axis=1) - first.mean(axis=1) <= np.maximum(0.1 * spread, 2.0 * error)


def _mean_and_spread(
    ax, x: np.ndarray, rows: np.ndarray, colour: str, band: bool, label: str, failed: np.ndarray | None = None
) -> None:
    """The mean over the seeds (rows) that learned, and either its 95% t-interval as a band or each of those
    seeds as a thin line; the seeds that never learned (``failed``) as thin dashed lines, outside the mean."""
    failed = np.zeros(len(rows), dtype=bool) if failed is None else failed
    for row in rows[failed]:
        ax.plot(x, row, color=colour, lw=0.9, ls=(0, (3, 1.5)), alpha=0.85)
    learned = rows[~failed]
    if not len(learned):
        ax.plot([], [], color=colour, lw=0.9, ls=(0, (3, 1.5)), label=label)
        return
    mean, half = mean_ci95(learned)
    if band:
        ax.fill_between(x, mean - half, mean + half, color=colour, alpha=0.2, lw=0)
    else:
        for row in learned:
            ax.plot(x, row, color=colour, lw=0.7, alpha=0.4)
    ax.plot(x, mean, color=colour, lw=1.8, label=label)


def _label(name: str, seeds: int, failed: int) -> str:
    plural = "s" if seeds != 1 else ""
    if not failed:
        return f"{name} ({seeds} seed{plural})"
    if failed == seeds:
        return f"{name} ({seeds} seed{plural}, none learned: each dashed)"
    return f"{name} ({seeds} seeds; {failed} never learned: dashed, not in the mean)"


def learning_curves_figure(
    curves: Mapping[str, Sequence[np.ndarray]],
    cells: Mapping[str, Sequence[np.ndarray]] | None = None,
    window: int = 20,
    ylabel: str = "steps per trial",
    title: str | None = None,
    xlabel: str = "trial",
    higher_is_better: bool = False,
    success: float | None = None,
):
    """Learning curves, one line per agent (or configuration): the mean over seeds and its spread, as a
    Matplotlib ``Figure`` (the caller closes it; :func:`plot_learning_curves` writes it to a file).

    The spread is the 95% t-interval of the mean with at least :data:`MIN_SEEDS_FOR_INTERVAL`
    seeds for every curve, else each seed as a thin line. Seeds that never learned (:func:`never_learned`)
    are left out of the mean and its spread and drawn each as a thin dashed line, and the legend says how
    many there are. Curves are trailing means over
    ``window`` trials (:func:`running_mean`; at most a tenth of the shortest run), drawn from
    the first whole window. The legend goes below the panels.

    Args:
        curves: agent -> one array per seed (e.g. steps per trial).
        cells: agent -> one array per seed of codebook size per trial (a second panel,
            which names the agents of ``curves`` it leaves out).
        window: Trailing-mean window.
        ylabel: The label of the values' axis.
        title: First line of the title; the second says what is drawn.
        xlabel: The label of the trials' axis (and the unit of the window, in the title).
        higher_is_better: Whether a higher value is better (a return; False: steps per trial).
        success: The level a seed's last tenth must reach to count as having learned, where the task has one.
    """
    plt = pyplot()
    from matplotlib.ticker import MaxNLocator

    two = bool(cells)
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(11 if two else 6.5, 4.2), squeeze=False)
    ax = axes[0, 0]
    failed = {name: never_learned(runs, higher_is_better, success) for name, runs in curves.items()}
    learned = [int((~f).sum()) for f in failed.values() if (~f).any()]
    band = bool(learned) and min(learned) >= MIN_SEEDS_FOR_INTERVAL
    shortest = min(len(r) for runs in curves.values() for r in runs)
    window = max(1, min(int(window), shortest // 10))
    colour = {name: f"C{k % 10}" for k, name in enumerate(curves)}
    for name, runs in curves.items():
        n = min(len(r) for r in runs)
        means = [running_mean(np.asarray(r[:n], float), window) for r in runs]
        label = _label(name, len(runs), int(failed[name].sum()))
        _mean_and_spread(ax, means[0][0], np.stack([m for _, m in means]), colour[name], band, label, failed[name])
    spread = "mean over seeds and its 95% t-interval" if band else "mean over seeds (thick) and each seed (thin)"
    smoothing = f", each a {window}-{xlabel} trailing mean" if window > 1 else ""
    dashed = ""
    if any(f.any() for f in failed.values()):
        rule = f"last tenth short of {success:g}" if success is not None else "last tenth not clearly better than first"
        dashed = f";\ndashed: a seed that never learned ({rule}), outside the mean"
    ax.set_title(f"{title or 'learning curves'}\n({spread}{smoothing}{dashed})", fontsize=10)
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
    fig.legend(
        handles,
        labels,
        loc="upper center",
        bbox_to_anchor=(0.5, 0.0),
        ncol=min(3, len(labels)),
        fontsize=8,
        frameon=False,
    )
    return fig


def plot_learning_curves(curves: Mapping[str, Sequence[np.ndarray]], path: str | os.PathLike, **options: Any) -> Path:
    """:func:`learning_curves_figure` written to ``path`` (its suffix picks the format); ``options`` are that
    function's keyword arguments (``cells``, ``window``, ``ylabel``, ``title``, ``xlabel``, ``higher_is_better``,
    ``success``), with its defaults. Returns ``path``."""
    fig = learning_curves_figure(curves, **options)
    out = save_figure(fig, path)
    pyplot().close(fig)
    return out
