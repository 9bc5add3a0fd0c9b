"""How the general ``avq`` defaults (``avq-sarsa`` since the planning agent became ``avq`` on these tasks) for
repeating a decision (``max_repeat``) and for the budget of cells
(``max_cells``) were chosen: ``avq`` with its ``"*"`` defaults on CartPole-v1 (no ``obs_bounds``), MountainCar-v0
and Acrobot-v1, 300 episodes, every pair of ``max_repeat`` and ``max_cells`` given.

Each run appends one row to docs/data/tune_general.csv: the final return (mean return of the last 10% of the
episodes), the cells at the end, at most and after 30 and 100 episodes, the growth refused at the budget, the env
steps and the wall time. ``table`` prints, per task and setting, the final return median [min-max] over the seeds
and the cells at the end (median [min-max]).

    python scripts/tune_general.py run tune 0,1,2 none 10000 Acrobot-v1     # the defaults of before (slow there)
    python scripts/tune_general.py run tune 0,1,2 none,1,2,4,8 256,1024
    python scripts/tune_general.py run tune 0,1,2 none,1,2,4,8 10000 CartPole-v1,MountainCar-v0
    python scripts/tune_general.py run confirm 10,11,12,13,14 none 10000,2048,1024 Acrobot-v1
    python scripts/tune_general.py run confirm 10,11,12,13,14 none,8 10000,2048,1024 CartPole-v1,MountainCar-v0
    python scripts/tune_general.py table tune
    python scripts/tune_general.py table confirm

(``run PHASE SEEDS MAX_REPEATS MAX_CELLS [TASKS]``: the rows of every combination; ``none`` is ``max_repeat=None``.)

Two jobs at a time (joblib). Held-out seeds (10-14) are never used for choosing among the tuning settings: only
to confirm, against the defaults of before, the setting the tuning seeds chose.
"""

from __future__ import annotations

import csv
import os
import sys
import time

import numpy as np

OUT = "docs/data/tune_general.csv"
TASKS = ("CartPole-v1", "MountainCar-v0", "Acrobot-v1")
EPISODES = 300
FIELDS = [
    "phase",
    "task",
    "max_repeat",
    "max_cells",
    "seed",
    "episodes",
    "final_return",
    "cells",
    "cells_max",
    "cells_30",
    "cells_100",
    "refused",
    "decisions",
    "env_steps",
    "wall_s",
]


def run(phase: str, task: str, max_repeat: int | None, max_cells: int, seed: int) -> dict:
    import gymnasium as gym

    import avq

    agent = avq.make_agent("avq-sarsa", gym.make(task), seed=seed, max_repeat=max_repeat, max_cells=max_cells)
    t0 = time.perf_counter()
    agent.learn(total_episodes=EPISODES)
    h = agent.episode_history()
    return dict(
        phase=phase,
        task=task,
        max_repeat="none" if max_repeat is None else max_repeat,
        max_cells=max_cells,
        seed=seed,
        episodes=EPISODES,
        final_return=round(float(h["return"][-EPISODES // 10 :].mean()), 3),
        cells=agent.n_cells,
        cells_max=int(h["n_cells"].max()),
        cells_30=int(h["n_cells"][29]),
        cells_100=int(h["n_cells"][99]),
        refused=int(h["refused"].sum()),
        decisions=int(h["decisions"].sum()),
        env_steps=agent.num_timesteps,
        wall_s=round(time.perf_counter() - t0, 1),
    )


def save(row: dict, out: str = OUT, fields: list[str] = FIELDS) -> None:
    """Append ``row`` to the CSV ``out`` (its header ``fields`` first, when the file is new)."""
    new = not os.path.exists(out)
    with open(out, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        if new:
            w.writeheader()
        w.writerow(row)


def spread(values: list[float], fmt: str) -> str:
    return f"{np.median(values):{fmt}} [{min(values):{fmt}}, {max(values):{fmt}}]"


def table(phase: str) -> str:
    """The rows of ``phase`` as a Markdown table: a line per setting, a column per task."""
    with open(OUT, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["phase"] == phase]
    settings = sorted(
        {(r["max_repeat"], int(r["max_cells"])) for r in rows},
        key=lambda s: (s[1], -1 if s[0] == "none" else int(s[0])),
    )
    seeds = sorted({int(r["seed"]) for r in rows})
    lines = [
        f"Seeds {', '.join(map(str, seeds))}; final return median [min, max] over the seeds / cells at the end "
        "(median [min, max]).",
        "",
        "| max_repeat | max_cells | " + " | ".join(TASKS) + " |",
        "|---|---|" + "---|" * len(TASKS),
    ]
    for mr, mc in settings:
        cells = []
        for task in TASKS:
            sel = [r for r in rows if r["task"] == task and r["max_repeat"] == mr and int(r["max_cells"]) == mc]
            if not sel:
                cells.append("")
                continue
            ret = spread([float(r["final_return"]) for r in sel], ".1f")
            n = spread([int(r["cells"]) for r in sel], ".0f")
            cells.append(f"{ret} / {n}")
        lines.append(f"| {mr} | {mc} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str]) -> None:
    if argv[0] == "table":
        print(table(argv[1]))
        return
    from joblib import Parallel, delayed

    phase, seeds, repeats, budgets = argv[1], argv[2], argv[3], argv[4]
    tasks = argv[5].split(",") if len(argv) > 5 else TASKS
    jobs = [
        (phase, task, None if mr == "none" else int(mr), int(mc), int(seed))
        for task in tasks
        for mc in budgets.split(",")
        for mr in repeats.split(",")
        for seed in seeds.split(",")
    ]
    jobs.sort(key=lambda j: -j[3])  # the slowest (largest budgets) first, so that the two jobs end together
    for row in Parallel(n_jobs=2, return_as="generator_unordered")(delayed(run)(*job) for job in jobs):
        save(row)
        print(row, flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
