"""Figures: the partition of a maze (the paper's Fig. 4), its animation as it learns, and learning curves.

Plotting reads results; it never trains. Matplotlib is used with the Agg backend and imported only
here, on first use.
"""

from avq.plotting.animation import animate_partition
from avq.plotting.curves import (
    MIN_SEEDS_FOR_INTERVAL,
    learning_curves_figure,
    mean_ci95,
    plot_learning_curves,
    running_mean,
)
from avq.plotting.partition import plot_partition, plot_partitions

__all__ = [
    "plot_partition",
    "plot_partitions",
    "animate_partition",
    "plot_learning_curves",
    "learning_curves_figure",
    "running_mean",
    "mean_ci95",
    "MIN_SEEDS_FOR_INTERVAL",
]
