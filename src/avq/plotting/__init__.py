"""Figures: the partition of a maze (the paper's Fig. 4), its animation as it learns, learning curves, and the
partition and greedy actions of an agent on any ``Box`` task over two chosen dimensions (:func:`plot_policy`).

Plotting reads results; it never trains. Matplotlib is used with the Agg backend and imported only
here, on first use.
"""

from avq.plotting.animation import animate_partition
from avq.plotting.curves import (
    MIN_SEEDS_FOR_INTERVAL,
    learning_curves_figure,
    mean_ci95,
    never_learned,
    plot_learning_curves,
    running_mean,
)
from avq.plotting.partition import plot_partition, plot_partitions
from avq.plotting.policy import plot_model, plot_policy
from avq.plotting.policy_data import PolicyMap, policy_map

__all__ = [
    "plot_partition",
    "plot_partitions",
    "animate_partition",
    "plot_policy",
    "plot_model",
    "policy_map",
    "PolicyMap",
    "plot_learning_curves",
    "learning_curves_figure",
    "running_mean",
    "mean_ci95",
    "never_learned",
    "MIN_SEEDS_FOR_INTERVAL",
]
