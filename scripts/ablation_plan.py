"""Ablation of avq-plan: each mechanism switched off in turn, on seeds and mazes held out from tuning.

The defaults were explored on ``lau2002`` refined k = 1, 2, 4 and on ``random_layout(side, side, 0.2,
seed=1000 + side)`` for sides 22 and 42, agent seeds 0-2. Here: ``lau2002`` refined k = 1, 2, 4 with agent
seeds 100-104, and five generated mazes of side 22 (``seed=2000 + i``, never used for tuning), one agent
seed each. The figure is the env steps until the greedy policy first succeeds from 95% of the starts
(budget 300,000 steps; censored runs count at the budget) and the cells then.

Rows:

* ``default``: ``avq-plan`` as registered;
* ``no model``: ``avq`` (Sarsa(λ) on the cells, no model; its maze defaults);
* ``no optimism``: untried pairs worth the floor (``v_opt = v_min``), ε-greedy with ε 0.1 instead;
* ``no collision growth``, ``no outcome split``: each growth rule off; ``cycle split on``: the option on;
* ``budget 0``, ``budget 10``, ``budget 1000``: backups per transition beyond the pair's own state;
* ``tabular-ps``: the reference.

    python scripts/ablation_plan.py            # about 10 minutes on 2 cores
"""

from __future__ import annotations

import csv
import statistics
import sys
import time
from pathlib import Path

import gymnasium as gym
from joblib import Parallel, delayed

import avq
from avq.envs import parse_layout, random_layout, refine_layout

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from ablation_avq import SARSA_AVQ  # noqa: E402  (the Sarsa(λ) agent avq was on the grid maze)
from scaling import learn_until  # noqa: E402

VARIANTS = {
    "default": ("avq-plan", {}),
    "no model (avq)": ("avq-maze", {**SARSA_AVQ, "max_cells": 1_000_000}),
    "no optimism": ("avq-plan", {"v_opt": -10_000.0, "epsilon": 0.1}),
    "no collision growth": ("avq-plan", {"collision_growth": False}),
    "no outcome split": ("avq-plan", {"outcome_split": False}),
    "cycle split on": ("avq-plan", {"cycle_split": True}),
    "budget 0": ("avq-plan", {"n_backups": 0}),
    "budget 10": ("avq-plan", {"n_backups": 10}),
    "budget 1000": ("avq-plan", {"n_backups": 1000}),
    "tabular-ps": ("tabular-ps", {}),
}
MAZES = {f"lau2002 k={k}": (lambda k=k: refine_layout("lau2002", k), range(100, 105)) for k in (1, 2, 4)}
MAZES.update(
    {f"generated 22 #{i}": (lambda i=i: random_layout(22, 22, 0.2, seed=2000 + i), (100 + i,)) for i in range(5)}
)
BUDGET = 300_000


def run(variant: str, maze: str, seed: int) -> dict:
    name, overrides = VARIANTS[variant]
    rows = MAZES[maze][0]()
    limit = 4 * (len(rows) + len(rows[0]))
    make = lambda: gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=limit)  # noqa: E731
    agent = avq.make_agent(name, make(), seed=seed, **overrides)
    t = time.perf_counter()
    reached, success, _ = learn_until(agent, make(), BUDGET, 0.95, max_steps=limit)
    return {
        "variant": variant,
        "maze": maze,
        "squares": parse_layout(rows).n_states,
        "seed": seed,
        "reached": reached,
        "env_steps": agent.num_timesteps,
        "cells": agent.n_cells,
        "success": success,
        "backups": getattr(agent, "backups_", 0),
        "queued": getattr(agent, "queued_", 0),
        "wall_s": round(time.perf_counter() - t, 2),
    }


def main() -> None:
    jobs = [(v, m, s) for m, (_, seeds) in MAZES.items() for v in VARIANTS for s in seeds]
    print(f"{len(jobs)} runs")
    rows = Parallel(n_jobs=-1)(delayed(run)(*job) for job in jobs)
    out = Path("docs/data/ablation_plan.csv")
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    groups = {
        "lau2002 k=1": ["lau2002 k=1"],
        "lau2002 k=2": ["lau2002 k=2"],
        "lau2002 k=4": ["lau2002 k=4"],
        "generated 22 (5 mazes)": [m for m in MAZES if m.startswith("generated")],
    }
    print(f"\n{'variant':<22}" + "".join(f"{g:>34}" for g in groups))
    for variant in VARIANTS:
        cells = []
        for mazes in groups.values():
            rs = [r for r in rows if r["variant"] == variant and r["maze"] in mazes]
            steps = [r["env_steps"] for r in rs]
            got = sum(r["reached"] for r in rs)
            mark = "" if got == len(rs) else ">"
            cells.append(
                f"{mark}{int(statistics.median(steps)):,} [{min(steps):,}-{max(steps):,}] "
                f"{got}/{len(rs)} c{int(statistics.median(r['cells'] for r in rs))}"
            )
        print(f"{variant:<22}" + "".join(f"{c:>34}" for c in cells))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
