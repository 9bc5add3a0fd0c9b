"""Choose the defaults of the general ``avq`` agent by measurement.

Runs AVQSarsa with the value-change trigger on (and optionally the reward trigger)
over a grid of settings on three tasks with different character, for a few seeds:
MountainCar-v0 (no collisions, sparse progress), CartPole-v1 (unbounded velocities,
given obs_bounds), the lau2002 GridMaze and RobotMaze (collisions). Each
configuration is scored by its mean rank over the tasks (mean return of the last
100 episodes on the control tasks, greedy success from every start on the mazes). Results go to a CSV.

    python scripts/sweep_avq_defaults.py --seeds 2 --episodes 300 --out sweep-avq.csv
"""

from __future__ import annotations

import argparse
import csv
import itertools

import gymnasium as gym
import numpy as np
from joblib import Parallel, delayed

from avq import AVQSarsa, evaluate_maze

CARTPOLE_BOUNDS = [(-2.4, 2.4), (-3.0, 3.0), (-0.21, 0.21), (-3.5, 3.5)]

GRID = {
    "value_trigger": [1.0, 5.0, 20.0],
    "d_min": [0.02, 0.05, 0.1],
    "alpha": [0.1, 0.3],
    "epsilon": [0.01, 0.05],
    "rho": [0.1, 1.0],
}
FIXED = dict(lam=0.7, gamma=1.0, chi=-50.0, q_init=0.0, merge_every=1, merge_age=5)
TASKS = ("MountainCar-v0", "CartPole-v1", "avq/GridMaze-v0", "avq/RobotMaze-v0")


def run(task: str, cfg: dict, seed: int, episodes: int) -> dict:
    kw = {**FIXED, **cfg}
    if task == "CartPole-v1":
        kw["obs_bounds"] = CARTPOLE_BOUNDS
    env = gym.make(task)
    agent = AVQSarsa(env, seed=seed, **kw).learn(total_episodes=episodes)
    h = agent.episode_history()
    score = float(np.mean(h["return"][-100:]))
    if task in ("avq/GridMaze-v0", "avq/RobotMaze-v0"):
        score = evaluate_maze(agent, gym.make(task))["success_rate"]
    return {
        "task": task,
        **cfg,
        "seed": seed,
        "score": score,
        "n_cells": agent.n_cells,
        "env_steps": agent.num_timesteps,
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--episodes", type=int, default=300)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="sweep-avq.csv")
    args = ap.parse_args()
    configs = [dict(zip(GRID, vals)) for vals in itertools.product(*GRID.values())]
    rows = Parallel(n_jobs=args.jobs)(
        delayed(run)(t, c, s, args.episodes) for t, c, s in itertools.product(TASKS, configs, range(args.seeds))
    )
    with open(args.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    # mean score per (task, config), then mean rank over tasks
    keys = list(GRID)
    table: dict[tuple, dict[str, float]] = {}
    cells: dict[tuple, list[int]] = {}
    for r in rows:
        k = tuple(r[x] for x in keys)
        table.setdefault(k, {}).setdefault(r["task"], []).append(r["score"])
        cells.setdefault(k, []).append(r["n_cells"])
    means = {k: {t: float(np.mean(v)) for t, v in d.items()} for k, d in table.items()}
    ranks = {k: 0.0 for k in means}
    for t in TASKS:
        order = sorted(means, key=lambda k: -means[k][t])
        for rank, k in enumerate(order):
            ranks[k] += rank / len(TASKS)
    for k in sorted(ranks, key=ranks.get)[:10]:
        print(
            dict(zip(keys, k)),
            {t: round(means[k][t], 2) for t in TASKS},
            "mean rank",
            round(ranks[k], 1),
            "cells",
            int(np.median(cells[k])),
        )


if __name__ == "__main__":
    main()
