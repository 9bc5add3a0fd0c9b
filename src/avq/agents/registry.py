"""Agents by name: ``make_agent("avq-paper", env)``, and the one table of their defaults.

:data:`DEFAULTS` is where every named agent's defaults live: for each name, its
defaults everywhere (``"*"``) and, for some environments, the defaults that replace
those (all of them) there, as RL Zoo keeps hyper-parameters per environment: ``avq``
takes the collision-driven maze rules on ``avq/GridMaze-v0`` and ``avq/RobotMaze-v0``,
and ``avq`` and ``avq-plan`` have entries for ``Acrobot-v1``, ``CartPole-v1`` and ``CartPole-v0`` (their metric
weighted per dimension, and more). Explicit parameters given to :func:`make_agent` win over both; the class's own
signature defaults fill in what an entry leaves out. :func:`make_agent` records on the agent which entry it used
(``agent.defaults_used``, a :class:`DefaultsUsed`) and ``avq train`` prints it.

:data:`AGENTS` (name -> class and ``"*"`` defaults) and :data:`TASK_DEFAULTS`
(name -> the per-environment entries) are views of :data:`DEFAULTS`, kept for the
code that reads them; they hold the same dicts, not copies.

The defaults of ``avq-paper`` were chosen by the sweep in
``scripts/sweep_paper_defaults.py`` (see docs/RESULTS.md, "How the defaults were
chosen"; the raw results are in docs/data/sweep-paper-defaults.csv).
"""

from __future__ import annotations

import inspect
from typing import Any, NamedTuple

import gymnasium as gym

from avq.agents.actions.agent import ActionCodebookSarsa
from avq.agents.plan.agent import PlanningAVQ
from avq.agents.avq_sarsa.agent import AVQSarsa
from avq.agents.base import BaseAgent
from avq.agents.baselines.grid import GridSarsa
from avq.agents.plan.sweeping import PrioritizedSweeping
from avq.agents.baselines.tabular import TabularSarsa
from avq.agents.baselines.tiles import TileSarsa

__all__ = ["AGENTS", "CLASSES", "DEFAULTS", "DefaultsUsed", "PLANNING_PARAMS", "SUMMARIES", "TASK_CLASSES",
           "TASK_DEFAULTS", "agent_class", "agent_defaults", "defaults_key", "make_agent"]

#: name -> the agent's class (for ``avq``: its class everywhere but the environments of :data:`TASK_CLASSES`).
CLASSES: dict[str, type[BaseAgent]] = {
    "avq-paper": AVQSarsa, "avq": PlanningAVQ, "avq-sarsa": AVQSarsa, "avq-maze": AVQSarsa, "tabular": TabularSarsa,
    "grid": GridSarsa, "tiles": TileSarsa, "tabular-ps": PrioritizedSweeping, "grid-ps": PrioritizedSweeping,
    "avq-plan": PlanningAVQ,
    "avq-actions": ActionCodebookSarsa, "uniform-actions": ActionCodebookSarsa,
}

# Beyond the paper, for tasks that report collisions (mazes, robots): the paper's
# collision-driven rules, plus a split where a cell's greedy action hits a wall
# (collision_split), and merging of any nearest pair of cells that share their greedy
# action (merge_pairs="nearest", merge_same_action, rho high enough to merge on the action
# alone), with at most 30 cells. Chosen with scripts/sweeps/ on lau2002 (docs/RESULTS.md,
# "Beyond the paper"). (Named here because ``avq``'s maze entries start from it.)
_AVQ_MAZE = dict(alpha=0.5, lam=0.7, gamma=1.0, epsilon=0.05, d_min=1.5, rho=200.0, chi=-50.0, q_init=5.0,
                 traces="replacing", merge_every=1, value_trigger=None, scale=1.0, collision_split=True,
                 merge_same_action=False, merge_pairs="nearest", max_cells=30)

# avq-plan on the mazes (below).
_PLAN_MAZE = dict(gamma=1.0, epsilon=0.0, v_opt=10.0, v_min=-10_000.0, known_after=1, n_backups=100, tol=0.01,
                  d_min=0.02, collision_growth=True, outcome_split=True, cycle_split=False, split_threshold=10.0,
                  value_slope=None, memory=100_000, scale=None, max_cells=10_000, split_after=None)

# avq-plan on tasks without collisions, and avq there (below).
_PLAN_GENERAL = dict(gamma=1.0, epsilon=0.0, v_opt="auto", v_min=-10_000.0, known_after=2, n_backups=100, tol=0.01,
                     d_min=0.05, collision_growth=True, outcome_split=True, cycle_split=False, split_threshold=10.0,
                     value_slope=None, memory=100_000, scale="auto", max_cells=2048, split_after=5)

# On Acrobot-v1, whose velocity bounds (±4π, ±9π) are far wider than the velocities a run sees, the metric's
# scale of every dimension is estimated from the first observations (scale "spread"): final return -132 against
# -350 with the bounds' ranges (tuning seeds 0-2, 300 episodes). On CartPole-v1 and MountainCar-v0 "spread"
# cost (306 against 500; -159 against -122): there the first observations span too little of what the agent
# later visits. And the angles' four components (cos and sin of each joint) count a third as much as the two
# velocities (scale_factor 3 on them; a guess at why: swinging up is mostly a matter of timing the torque to the
# velocities, so cells as fine in the angles spend the budget where decisions agree). Seeds 0-9, 500 episodes:
# -120.9 ± 5.1 against -136 ± 13 without (factors 2 and 3, velocities at 1 or 0.7, all gave -119.6 to -125.2;
# tiles -128 ± 11). Untried decisions are worth -100 (v_opt), the return at which
# Gymnasium calls the task solved (its spec's reward_threshold), not 0 ("auto": the best any reward allows):
# with 0 the agent explores every new cell until the budget is full and improves only then (a 20-episode
# mean of -150 after 68k-85k env steps); with -100 it gets there after 5k-25k (median 15k; tiles on the
# held-out seeds 16k-48k), ends as high (-121.8 ± 10.3) in 1,260 cells, at half the time. Anything from -75
# to -150 did as well; on MountainCar less optimism cost (-137 at its threshold, -110, against -127.5).
# docs/RESULTS.md, "The general agent: how the planning defaults were chosen".
_PLAN_ACROBOT = {**_PLAN_GENERAL, "scale": "spread", "scale_factor": [3.0, 3.0, 3.0, 3.0, 1.0, 1.0],
                 "v_opt": -100.0}

# On CartPole-v1, ε-greedy exploration (epsilon 0.01) on top of the optimism. Without it, about one seed in ten
# settles on a policy that balances the pole while the cart drifts off the track in ~150 steps: the planner's
# greedy policy never visits the states that would teach it to drift back. With it, seeds 0-9 (500 episodes):
# final return 494 ± 8 (lowest 474) against 469 ± 83 (lowest 221), greedy success 100% on every seed against
# 84.5% on average. On MountainCar and Acrobot ε costs (-131 against -127; -161 against -132). And the pole's
# angle and angular velocity count twice as much as the cart's position and velocity (scale_factor 0.5 on
# them): on seeds 30-49 (run to study the seeds whose greedy policy fails) greedy success 99.7% against 94.3%,
# final return 498.4 ± 2.6 against 495.2 ± 10.0; on seeds 0-9 99.5% against 100%, 495.5 ± 7.6 against 494 ± 8,
# a mean of 195 after 5.5k env steps against 6.8k, in about 1,050 cells against 800. The cart's dimensions
# twice as coarse instead ([2, 2, 1, 1]) did half as well (97.2%). docs/RESULTS.md, "The general agent: how
# the planning defaults were chosen". CartPole-v0 is the same cart and pole with a 200-step limit, and it takes
# the same entry: on its tuning seeds 0-9 (500 episodes) greedy success 100% on every seed against 93% with the
# general defaults, a mean of 195 after 9.3k env steps against 13k.
_PLAN_CARTPOLE = {**_PLAN_GENERAL, "epsilon": 0.01, "scale_factor": [1.0, 1.0, 0.5, 0.5]}

#: name -> {"*": its defaults, environment id: the defaults that replace them (all of them) there}.
DEFAULTS: dict[str, dict[str, dict[str, Any]]] = {
    # The paper's rules exactly: collision trigger only, plain Euclidean metric
    # (scale 1, d_min in the environment's units), merge after every trial.
    "avq-paper": {
        "*": dict(alpha=0.5, lam=0.7, gamma=1.0, epsilon=0.05, d_min=1.0, rho=5.0, chi=-50.0,
                  q_init=5.0, traces="replacing", merge_every=1, value_trigger=None, scale=1.0),
    },
    # AVQ, our best: on tasks without collisions (classic control) the planning agent with its general defaults
    # (avq-plan's "*", below: docs/RESULTS.md, "The general agent on classic control"); on the mazes the model-free
    # maze rules (the class there is AVQSarsa: TASK_CLASSES).
    #
    # On the grid maze, ``avq`` is ``avq-maze`` plus the cycle split and a decaying exploration rate (ε 0.2,
    # times 0.995 per episode, down to 0.01). Chosen on 150 seeds of ``lau2002`` and 100 generated mazes, among
    # the settings of scripts/ablation_avq.py (docs/RESULTS.md, "Beyond the paper"): 85% of the seeds meet all
    # three goals (success >= 95%, path ratio <= 1.15, <= 30 cells; 78% without the schedule, 85% for avq-maze),
    # mean success 0.980 (0.978, 0.970), 0.869 on the generated mazes (0.855, 0.842), in about 17.3k env steps
    # (20.5k, 21.5k; tabular 17.5k). On RobotMaze the cycle split cost success (0.52 against 0.61, 300 episodes,
    # 10 seeds), and the 30-cell cap is the grid maze's budget, so there ``avq`` is ``avq-maze`` without the cap
    # (the general ``avq-sarsa`` reached 0.24, ``tiles`` 0.85).
    "avq": {
        "*": _PLAN_GENERAL,
        "Acrobot-v1": _PLAN_ACROBOT,
        "CartPole-v1": _PLAN_CARTPOLE,
        "CartPole-v0": _PLAN_CARTPOLE,
        "avq/GridMaze-v0": {**_AVQ_MAZE, "cycle_split": True, "epsilon": 0.2, "epsilon_decay": 0.995,
                            "epsilon_min": 0.01},
        "avq/RobotMaze-v0": {**_AVQ_MAZE, "max_cells": 10_000},
    },
    # AVQ Sarsa(λ) for any task (``avq``'s general defaults before the planning agent replaced them): collisions
    # when the env reports them, plus the value-change trigger (SPEC §3) so that tasks without collisions grow a
    # partition too; a merge guard so that value-triggered cells (copies of their parent) get time to differ
    # before a merge pass. Metric scaled by the observation bounds, and where they are not finite by the spread
    # of the first observations (scale="auto"; obs_bounds= wins for the dimensions it bounds).
    # Chosen by scripts/sweep_avq_defaults.py (docs/RESULTS.md, "The general avq agent").
    # A budget of 2048 cells, half of tiles' 4096 features, and one decision per cell repeated until the cell
    # changes (max_repeat None), chosen by scripts/tune_general.py (docs/RESULTS.md, "The general avq agent:
    # repeating a decision, and a budget of cells"; 300 episodes, seeds 0-2, confirmed on 10-14): on CartPole-v1
    # and MountainCar-v0 the partition stays under 700 cells (881 in 500 episodes) and the budget changes
    # nothing; on Acrobot-v1 growth never stops (7,000-10,000 cells, at 10 times the wall time) while learning
    # little (-434 median against -486 at 2048 and -497 for a random policy). Bounding a decision to 1-8 steps
    # cost on MountainCar (-197 to -148 against -143) and helped nowhere clearly.
    "avq-sarsa": {
        "*": dict(alpha=0.3, lam=0.7, gamma=1.0, epsilon=0.05, d_min=0.05, rho=0.1, chi=-50.0,
                  q_init=0.0, traces="replacing", merge_every=1, merge_age=5, value_trigger=1.0,
                  reward_trigger=None, scale="auto", max_cells=2048, max_repeat=None),
    },
    "avq-maze": {"*": _AVQ_MAZE},
    "tabular": {
        "*": dict(alpha=0.1, lam=0.7, gamma=1.0, epsilon=0.1, q_init=0.0, traces="replacing"),
    },
    # Model-based: prioritized sweeping on one state per observation, optimistic about untried pairs
    # (worth the grid maze's goal reward), undiscounted as the paper's task, values floored at -10,000
    # (below any return of an episode on avq's mazes). n_backups: see docs/RESULTS.md, "Planning".
    "tabular-ps": {
        "*": dict(gamma=1.0, epsilon=0.0, v_opt=10.0, v_min=-10_000.0, known_after=1, n_backups=100, tol=0.01),
    },
    # The same planner on a fixed uniform grid (10 bins per dimension, as "grid"): the full-resolution
    # reference for avq-plan on continuous tasks (on RobotMaze, one bin per lattice step of the move).
    "grid-ps": {
        "*": dict(gamma=1.0, epsilon=0.0, v_opt=10.0, v_min=-10_000.0, known_after=1, n_backups=100, tol=0.01,
                  bins=10, obs_bounds=None),
    },
    # AVQ with a model of its cells and planning over it (docs/RESULTS.md, "Planning over the partition").
    # On the mazes: explored on lau2002 refined k = 1, 2, 4 and two generated mazes (sides 22, 42), seeds 0-9:
    # collision growth and the outcome split both on (without either, 1.5-2x the steps or failures); gamma 1
    # (0.99 and 0.95 took more steps); 100 backups a step (1000: about the same steps for 4x the backups; 10: a
    # failure); split_threshold 10 (5: cells 4.8x from k=1 to k=4, 10: 3.6x, and 1.17x tabular-ps's steps
    # at k=4 against 1.4x; 20 failed 2 of 50 runs). tol 0.01 (1e-6 left a tail of tiny changes circling the
    # aggregated model's cycles: 44 backups a step once learned on lau2002 against 0.8, at 0.09 M steps/s
    # against 0.63 M, with no fewer env steps on lau2002 k = 2, 4 and a generated maze of side 22).
    #
    # Elsewhere (tasks without collisions): a decision that stays split_after steps in its cell grows a cell
    # there, optimism from the rewards seen (v_opt "auto"), the metric estimated where the bounds are not
    # finite (scale "auto") and a budget of 2048 cells. Chosen by scripts/tune_plan_general.py
    # (docs/RESULTS.md, "The general agent on classic control").
    "avq-plan": {
        "*": _PLAN_GENERAL,
        "Acrobot-v1": _PLAN_ACROBOT,
        "CartPole-v1": _PLAN_CARTPOLE,
        "CartPole-v0": _PLAN_CARTPOLE,
        "avq/GridMaze-v0": _PLAN_MAZE,
        "avq/RobotMaze-v0": _PLAN_MAZE,
    },
    # The baselines. Their defaults were chosen by a quick measurement, described here with its
    # figures (the script is not in the repository): MountainCar-v0 (200-step limit) and CartPole-v1
    # (500-step limit, obs_bounds=[(-2.4, 2.4), (-3, 3), (-0.21, 0.21), (-3.5, 3.5)]), 300 episodes,
    # seeds 0-4, after a first pass of 200 episodes, seeds 0-2, over alpha 0.05-1, lambda 0.7 and 0.9
    # and epsilon 0-0.1. The figure compared is the mean steps per episode over the last 50 episodes
    # (below: MountainCar / CartPole, mean of the seeds); each setting was scored by the mean over the
    # two tasks of its learning above the no-learning floor (MountainCar 200 steps, CartPole 22.5
    # steps, a random policy), each relative to the best setting's.
    #
    # "grid": 10 bins per dimension and lambda 0.7 as in avq-paper and tabular (lambda 0.9 scored
    # about the same: best 0.57 against 0.53). alpha 0.5, epsilon 0.1 scored best (0.53: 196.9 /
    # 105.5; no lambda-0.7 setting got below 172.7 on MountainCar within 300 episodes); next were
    # alpha 0.5 with epsilon 0.02 (0.46: 178.8 / 63.7) and 0.05 (0.45: 191.7 / 83.4). With epsilon 0,
    # CartPole never learns (q_init 0 is pessimistic under +1 rewards: 28.9).
    "grid": {
        "*": dict(bins=10, obs_bounds=None, alpha=0.5, lam=0.7, gamma=1.0, epsilon=0.1, q_init=0.0,
                  traces="replacing"),
    },
    # "tiles": Sutton & Barto's Mountain Car agent (8 tilings of 8 x 8, alpha 0.5 in total, lambda 0.9,
    # q_init 0, replacing traces), but epsilon 0.05 instead of the book's 0: with epsilon 0, CartPole
    # stays at 10-14 steps for 2 seeds of 5 (108.7 / 185.0; with epsilon 0.05: 129.2 / 395.1), at a
    # cost of 20 steps on MountainCar. Scores: epsilon 0.05 0.89 (alpha 0.25: 0.89 too),
    # epsilon 0 0.72, 0.01-0.02 0.68-0.69. Pass epsilon=0 for the book's setting. The IHT never filled
    # (at most 2810 of 4096 tiles on CartPole).
    "tiles": {
        "*": dict(n_tilings=8, tiles_per_dim=8, iht_size=4096, obs_bounds=None, alpha=0.5, lam=0.9, gamma=1.0,
                  epsilon=0.05, q_init=0.0, traces="replacing"),
    },
    # AVQ on the action space, for continuous (Box) actions: "avq-actions" grows and merges an action
    # codebook from 3 values per action dimension; "uniform-actions" is the same learner on a fixed
    # uniform grid. The learner is that of "tiles" but for gamma 0.99 (Pendulum never terminates) and q_init 30
    # (MountainCarContinuous: from 0, 2 seeds of 2 learned to stand still, return -4 after 60 episodes;
    # from 30 both reached the flag, 91; on Pendulum, uniform 3 actions: -197 from 30, -183 from 0, 3 seeds,
    # within the seeds' spread). A quick measurement chose the rest (the script is not in the repository;
    # figures: mean return of the last 10% of episodes, Pendulum-v1 300 episodes, MountainCarContinuous-v0
    # 100): adapting every 10 episodes with rho 1 (no merges) grew to 17 actions and lost on Pendulum
    # (-226 vs -183 for uniform 3, seeds 0-2); rho 100 merged and regrew at every pass (-198, 4 actions,
    # seeds 3-6); adapt_every 10 / rho 30: Pendulum -172 (seeds 3-6), MountainCar 90.6 (seeds 0-4);
    # adapt_every 25 / rho 30: Pendulum -186 (seeds 0-6, 6-12 actions), MountainCar 92.2; uniform 3 (Pendulum
    # seeds 0-6): -183 / 91.3; uniform 5 (seeds 3-6): -180 / 92.4. All within the seeds' spread; the less
    # restless adapt_every 25 was kept.
    # Uniform 5 is the default grid: never worse than 3 here. docs/RESULTS.md, "AVQ on the action space".
    "avq-actions": {
        "*": dict(init_actions=3, fixed=False, max_actions=17, adapt_every=25, d_min=0.03, rho=30.0, memory=2000,
                  n_tilings=8, tiles_per_dim=8, iht_size=4096, obs_bounds=None, alpha=0.5, lam=0.9, gamma=0.99,
                  epsilon=0.05, q_init=30.0, traces="replacing"),
    },
    "uniform-actions": {
        "*": dict(init_actions=5, fixed=True, n_tilings=8, tiles_per_dim=8, iht_size=4096, obs_bounds=None,
                  alpha=0.5, lam=0.9, gamma=0.99, epsilon=0.05, q_init=30.0, traces="replacing"),
    },
}


#: name -> what the agent is: its class's rules as this name sets them (the reference's section per agent).
SUMMARIES: dict[str, str] = {
    "avq-paper": "AVQ with the paper's rules exactly: cells grow only on collisions (SPEC §3), the plain Euclidean "
                 "metric (`scale` 1: `d_min` in the environment's units), and a merge pass of mutually nearest cells "
                 "with similar action values after every trial (SPEC §4). On a task that reports no collisions it keeps "
                 "one cell: use `avq` there.",
    "avq": "AVQ, our best settings. On tasks without collisions (classic control, any `Box` task): the planning agent "
           "of `avq-plan` with its general defaults: a learned model of the cells, R-max optimism from the rewards seen "
           "(`v_opt` \"auto\"), growth where a decision stays `split_after` steps in its cell and where outcomes "
           "disagree (`outcome_split`), the metric estimated where the bounds are not finite (`scale` \"auto\"), and a "
           "budget of 2048 cells; on `Acrobot-v1` the metric's scale estimated from the observations for every "
           "dimension (`scale` \"spread\"), on `CartPole-v1` and `CartPole-v0` ε-greedy exploration (ε 0.01) on top "
           "of the optimism. On `avq/GridMaze-v0`: Sarsa(λ) with the rules of `avq-maze`, plus a split where two "
           "greedy decisions cycle between two cells (`cycle_split`) and a decaying exploration rate "
           "(`epsilon_decay`); on `avq/RobotMaze-v0`: `avq-maze` without its budget of cells.",
    "avq-sarsa": "AVQ Sarsa(λ) for any task (the general `avq` before the planning agent): growth on collisions when the "
                 "task reports them and where an action value changes by more than `value_trigger`, a merge-age guard "
                 "(`merge_age`), the metric scaled by the observation bounds, estimated from the observations where "
                 "they are not finite (`scale` \"auto\"; `obs_bounds=` wins), and a budget of 2048 cells.",
    "avq-maze": "AVQ beyond the paper, for tasks that report collisions: the paper's rules, plus a split where a cell's "
                "greedy action hits a wall (`collision_split`), merging of nearest pairs (`merge_pairs`), and a budget "
                "of cells (`max_cells`).",
    "tabular": "Sarsa(λ) with one table row per distinct observation, one decision per step: full resolution on the "
               "grid maze; on continuous observations it makes a row for every observation and cannot generalize.",
    "grid": "Sarsa(λ) on a fixed uniform discretization (`bins` per dimension): the fixed-resolution baseline.",
    "tiles": "Linear Sarsa(λ) with tile coding like Sutton's `tiles3` (`n_tilings` tilings, hashing into `iht_size` "
             "weights).",
    "tabular-ps": "Model-based: one state per distinct observation, a learned model (successor counts, mean rewards), "
                  "optimism for untried pairs (R-max's `v_opt`) and prioritized sweeping with `n_backups` backups per "
                  "step (Moore & Atkeson 1993). The strong baseline on the mazes.",
    "grid-ps": "The planner of `tabular-ps` on a fixed uniform grid (`bins` per dimension): full resolution with a "
               "model on continuous mazes.",
    "avq-plan": "AVQ's cells and decisions (one per cell, repeated until the cell changes) with a learned model of the "
                "cells (one decision an SMDP step), the planner of `tabular-ps`, and cells split where a decision's "
                "outcomes disagree beyond what distance explains (`outcome_split`, `split_threshold`). On the mazes: "
                "growth on collisions; elsewhere, the general defaults that `avq` uses there (`split_after`, `v_opt` "
                "\"auto\").",
    "avq-actions": "For continuous (`Box`) actions: the learner of `tiles` over an adaptive codebook of actions, from "
                   "`init_actions` values per action dimension, that grows (a midpoint next to the most used action) "
                   "and merges (similar value columns) every `adapt_every` episodes.",
    "uniform-actions": "The learner of `avq-actions` on a fixed uniform grid of `init_actions` actions per dimension "
                       "(`fixed`): the baseline for `avq-actions`.",
}


#: name -> {environment id -> the agent's class there}, where it is not :data:`CLASSES`' (``avq`` on the mazes).
TASK_CLASSES: dict[str, dict[str, type[BaseAgent]]] = {
    "avq": {"avq/GridMaze-v0": AVQSarsa, "avq/RobotMaze-v0": AVQSarsa},
}

#: name -> (class, its ``"*"`` defaults): a view of :data:`avq.agents.registry.DEFAULTS`.
AGENTS: dict[str, tuple[type[BaseAgent], dict[str, Any]]] = {name: (CLASSES[name], table["*"])
                                                             for name, table in DEFAULTS.items()}
#: name -> {environment id -> defaults} for the names with per-environment entries: a view of :data:`DEFAULTS`.
TASK_DEFAULTS: dict[str, dict[str, dict[str, Any]]] = {
    name: {env_id: d for env_id, d in table.items() if env_id != "*"} for name, table in DEFAULTS.items()
    if len(table) > 1
}


#: The options of the agents that learn a model and plan over it (``tabular-ps``, ``avq-plan``).
PLANNING_PARAMS = ("v_opt", "v_min", "known_after", "n_backups", "tol")


class DefaultsUsed(NamedTuple):
    """Which defaults :func:`make_agent` gave an agent: ``DEFAULTS[name][key]``, then ``explicit``."""

    name: str
    env_id: str | None
    #: The entry of ``DEFAULTS[name]`` used: ``"*"`` or an environment id.
    key: str
    #: The parameters given explicitly, which won over the entry.
    explicit: dict[str, object]

    def __str__(self) -> str:
        which = "the general defaults" if self.key == "*" else f"the {self.key} defaults"
        explicit = ", ".join(f"{k}={v!r}" for k, v in self.explicit.items()) or "none"
        return (f"agent {self.name} on {self.env_id or 'an unregistered environment'}: {which} of {self.name} "
                f"(avq.agents.registry.DEFAULTS[{self.name!r}][{self.key!r}]); explicit: {explicit}")


def defaults_key(name: str, env_id: str | None = None) -> str:
    """The entry of ``DEFAULTS[name]`` that holds agent ``name``'s defaults on ``env_id``: the id or ``"*"``."""
    if name not in DEFAULTS:
        raise ValueError(f"unknown agent {name!r}; known agents: {', '.join(sorted(DEFAULTS))}")
    return env_id if env_id is not None and env_id != "*" and env_id in DEFAULTS[name] else "*"


def agent_class(name: str, env_id: str | None = None) -> type[BaseAgent]:
    """The class of agent ``name`` on environment ``env_id``: :data:`CLASSES`' unless :data:`TASK_CLASSES` names
    another there (``avq`` is the planning agent on tasks without collisions, and Sarsa(λ) on the mazes)."""
    key = defaults_key(name, env_id)  # (an unknown name raises here)
    return TASK_CLASSES.get(name, {}).get(key, CLASSES[name])


def agent_defaults(name: str, env_id: str | None = None) -> dict[str, Any]:
    """The defaults of agent ``name``, on environment ``env_id`` if it has defaults of its own there."""
    key = defaults_key(name, env_id)
    return dict(DEFAULTS[name][key])


def _env_id(env: gym.Env | str) -> str | None:
    """The registered id of ``env``: its ``spec``, or for an environment built without ``gymnasium.make``
    the id registered for its class."""
    if isinstance(env, str):
        return env
    if not isinstance(env, gym.Env):
        return None  # the agent's constructor says what it needs
    spec = getattr(env, "spec", None)
    if spec is not None:
        return spec.id
    cls = type(env.unwrapped)
    target = f"{cls.__module__}:{cls.__qualname__}"
    return next((env_id for env_id, s in gym.registry.items() if s.entry_point == target), None)


def make_agent(name: str, env: gym.Env | str, seed: int | None = None, **overrides: Any) -> BaseAgent:
    """Create the agent registered as ``name`` with its defaults, updated by ``overrides``.

    The names, with each one's rules and defaults, are listed in `avq.agents.registry`. Some agents have
    defaults of their own on some environments (:data:`avq.agents.registry.DEFAULTS`): ``avq`` on
    ``avq/GridMaze-v0`` and ``avq/RobotMaze-v0`` uses the collision-driven maze rules. The
    environment is recognised by its registered id (``env.spec.id``, or the id registered for its class
    when it was built without ``gymnasium.make``). The agent's ``defaults_used`` says which entry
    was used and which parameters were explicit.

    Args:
        name: A registered name, such as ``"avq-paper"``, ``"avq"`` or ``"tabular"``.
        env: A Gymnasium environment, or a registered id to make one.
        seed: The seed of the agent's generators (None: fresh entropy).
        overrides: Parameters of the agent's class, which win over the defaults.

    Returns:
        The agent, not yet trained.

    Raises:
        ValueError: unknown name, or an override that is not a parameter of the agent.
    """
    env_id = _env_id(env)
    key = defaults_key(name, env_id)  # (an unknown name raises here)
    cls = agent_class(name, env_id)
    if "seed" in overrides:
        raise ValueError("seed is not an agent parameter here: pass it as seed= (on the command line, --seed)")
    valid = set(cls._param_names()) - {"seed"}
    unknown = sorted(set(overrides) - valid)
    planning = [p for p in unknown if p in PLANNING_PARAMS]
    if planning:
        plans = lambda n: set(PLANNING_PARAMS) <= set(agent_class(n, env_id)._param_names())  # noqa: E731
        with_model = ", ".join(repr(n) for n in CLASSES if plans(n))
        where = f" on {env_id or 'this environment'}" if name in TASK_CLASSES else ""
        raise ValueError(f"{planning[0]!r} is an option of planning over a learned model, and agent {name!r} has no "
                         f"model{where}; the agents that plan{where} are {with_model}")
    if unknown:
        raise ValueError(
            f"unknown parameter {unknown[0]!r} for agent {name!r}"
            + (f" on {env_id or 'this environment'} (class {cls.__name__})" if name in TASK_CLASSES else "")
            + f"; its parameters: {', '.join(sorted(valid))}"
        )
    agent = cls(env, **{**DEFAULTS[name][key], **overrides, "seed": seed})
    agent.defaults_used = DefaultsUsed(name, env_id, key, dict(overrides))
    return agent


def _reference() -> str:
    """The section of the API reference on the agents by name: each name's class, summary and defaults, read from
    :data:`CLASSES`, :data:`SUMMARIES` and :data:`DEFAULTS` (a parameter an entry leaves out shows the class's own
    default)."""
    parts = ["\n\n## The agents by name\n\nEach name's class, what it is, and its defaults: a column per entry of "
             "`avq.agents.registry.DEFAULTS`; a value the entry leaves out is the class's own default, marked "
             "*(class)*. Explicit parameters given to `avq.agents.registry.make_agent` win."]
    for name, table in DEFAULTS.items():
        classes = {key: agent_class(name, key) for key in table}
        signatures = {key: inspect.signature(cls.__init__).parameters for key, cls in classes.items()}
        rows = list(dict.fromkeys(key for entry in table.values() for key in entry))
        head = " | ".join(f"`{key}`" if key != "*" else "everywhere (`\"*\"`)" for key in table)
        lines = [f"| parameter | {head} |", "|---|" + "---|" * len(table)]
        for param in rows:
            cells = [f"`{entry[param]!r}`" if param in entry else
                     f"`{signatures[key][param].default!r}` *(class)*" if param in signatures[key] else "-"
                     for key, entry in table.items()]
            lines.append(f"| `{param}` | " + " | ".join(cells) + " |")
        if len(set(classes.values())) == 1:
            which = f"Class: `avq.agents.{CLASSES[name].__name__}`."
        else:
            which = "Class: " + "; ".join(f"`avq.agents.{cls.__name__}` " + ("everywhere else" if key == "*" else
                                                                             f"on `{key}`")
                                          for key, cls in sorted(classes.items(), key=lambda kv: kv[0] == "*")) + "."
        parts.append(f"### {name}\n\n{SUMMARIES[name]}\n\n{which}\n\n" + "\n".join(lines))
    return "\n\n".join(parts) + "\n"


if __doc__:  # (None under python -OO)
    __doc__ += _reference()
