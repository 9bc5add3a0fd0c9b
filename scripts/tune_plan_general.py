"""How the general defaults of ``avq-plan`` (a model of the cells and planning over it) were chosen for tasks
without collisions: ``avq-plan`` with its ``"*"`` defaults and each combination of the settings given, on
CartPole-v1 (no ``obs_bounds``), MountainCar-v0 and Acrobot-v1, 300 episodes.

Each run appends one row to docs/data/tune_plan_general.csv: the setting, the final return (mean return of the
last 10% of the episodes), the env steps until the mean return of 20 episodes first reached the task's threshold
(MountainCar -150, CartPole 195, Acrobot -100; empty if never), the cells at the end and after 30 and 100
episodes, the growth refused at the budget, the env steps and the wall time. ``table`` prints, per setting, the
final return median [min, max] over the seeds and the cells at the end per task, and the setting's mean rank.

    python scripts/tune_plan_general.py run tune 0,1,2 split_after=3,5,10 d_min=0.05,0.1,0.15 known_after=1,2
    python scripts/tune_plan_general.py table tune
    python scripts/tune_plan_general.py run confirm 10,11,12,13,14 split_after=5 d_min=0.1 known_after=2
    python scripts/tune_plan_general.py table confirm

(``run PHASE SEEDS NAME=V1,V2,... [NAME=...] [--tasks T1,T2]``: the rows of every combination; the values are
Python literals, ``none`` is None.) Two jobs at a time (joblib). Held-out seeds (10-14) are never used for
choosing: only to confirm the setting the tuning seeds chose.
"""

from __future__ import annotations

import ast
import csv
import itertools
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [HERE, os.path.join(HERE, os.pardir, "benchmarks")]
from compare import THRESHOLDS, steps_to_threshold  # noqa: E402  (benchmarks/compare.py: the same measures)
from tune_general import save as append_row  # noqa: E402

OUT = "docs/data/tune_plan_general.csv"
TASKS = ("CartPole-v1", "MountainCar-v0", "Acrobot-v1")
EPISODES = 300
FIELDS = [
    "phase",
    "task",
    "setting",
    "seed",
    "episodes",
    "final_return",
    "steps_to_threshold",
    "cells",
    "cells_30",
    "cells_100",
    "refused",
    "env_steps",
    "wall_s",
]


def run(phase: str, task: str, setting: dict, seed: int) -> dict:
    import gymnasium as gym

    import avq

    agent = avq.make_agent("avq-plan", gym.make(task), seed=seed, **setting)
    t0 = time.perf_counter()
    agent.learn(total_episodes=EPISODES)
    h = agent.episode_history()
    reached = steps_to_threshold(h["return"], h["steps"], THRESHOLDS[task])
    return dict(
        phase=phase,
        task=task,
        setting=json.dumps(setting, sort_keys=True),
        seed=seed,
        episodes=EPISODES,
        final_return=round(float(h["return"][-EPISODES // 10 :].mean()), 3),
        steps_to_threshold="" if reached is None else reached,
        cells=agent.n_cells,
        cells_30=int(h["n_cells"][29]),
        cells_100=int(h["n_cells"][99]),
        refused=int(h["refused"].sum()),
        env_steps=agent.num_timesteps,
        wall_s=round(time.perf_counter() - t0, 1),
    )


def save(row: dict) -> None:
    append_row(row, OUT, FIELDS)


def table(phase: str) -> str:
    """The rows of ``phase`` as a Markdown table: a line per setting (best mean rank first), a column per task."""
    with open(OUT, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["phase"] == phase]
    settings = sorted({r["setting"] for r in rows})
    seeds = sorted({int(r["seed"]) for r in rows})
    med = {
        (s, t): [float(r["final_return"]) for r in rows if r["setting"] == s and r["task"] == t]
        for s in settings
        for t in TASKS
    }
    ranks = {s: 0.0 for s in settings}
    for t in TASKS:
        order = sorted(settings, key=lambda s: -np.median(med[s, t]) if med[s, t] else np.inf)
        for k, s in enumerate(order):
            ranks[s] += k / len(TASKS)
    lines = [
        f"Seeds {', '.join(map(str, seeds))}; final return median [min, max] over the seeds / cells at the end "
        "(median) / runs that reached the threshold; settings by mean rank of the median over the tasks.",
        "",
        "| setting | mean rank | " + " | ".join(TASKS) + " |",
        "|---|---|" + "---|" * len(TASKS),
    ]
    for s in sorted(settings, key=lambda s: ranks[s]):
        cells = []
        for t in TASKS:
            mine = [r for r in rows if r["setting"] == s and r["task"] == t]
            if not mine:
                cells.append("-")
                continue
            f = [float(r["final_return"]) for r in mine]
            c = [int(r["cells"]) for r in mine]
            there = sum(r["steps_to_threshold"] != "" for r in mine)
            cells.append(f"{np.median(f):.1f} [{min(f):.1f}, {max(f):.1f}] / {np.median(c):.0f} / {there}/{len(mine)}")
        lines.append(f"| `{s}` | {ranks[s]:.1f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _value(text: str):
    return None if text == "none" else ast.literal_eval(text)


def main(argv: list[str]) -> int:
    if len(argv) >= 2 and argv[0] == "table":
        print(table(argv[1]))
        return 0
    if len(argv) < 3 or argv[0] != "run":
        print(__doc__)
        return 2
    from joblib import Parallel, delayed

    phase, seeds = argv[1], [int(s) for s in argv[2].split(",")]
    tasks, grid = TASKS, {}
    rest = argv[3:]
    if "--tasks" in rest:
        k = rest.index("--tasks")
        tasks, rest = tuple(rest[k + 1].split(",")), rest[:k] + rest[k + 2 :]
    for item in rest:
        name, values = item.split("=", 1)
        grid[name] = [_value(v) for v in values.split(",")]
    settings = [dict(zip(grid, combo)) for combo in itertools.product(*grid.values())]
    jobs = [(phase, t, s, seed) for t in tasks for s in settings for seed in seeds]
    for row in Parallel(n_jobs=2, return_as="generator_unordered")(delayed(run)(*j) for j in jobs):
        save(row)
        print(row["task"], row["setting"], row["seed"], row["final_return"], row["cells"], row["wall_s"], flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
