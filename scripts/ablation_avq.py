"""The ablation of the Sarsa(λ) agent that ``avq`` was on grid mazes: each option switched off (or on) in turn.

Every row trains for 1000 trials from random starts and walks the greedy policy from
every start (``avq.evaluate_maze``):

* ``lau2002``, agent seeds 0-29 (the first ten are the seeds of ``avq reproduce``);
* 20 generated mazes, ``random_layout(13, 13, 0.2, seed=m)`` for m = 0-19 (90-100 free
  squares, none of them used to choose the defaults), agent seed 0 on each.

"All three" counts the runs that meet every goal at once: greedy success >= 95%, path
ratio <= 1.15 and at most 30 cells.

    python scripts/ablation_avq.py                      # about 3 minutes on 2 cores
    python scripts/ablation_avq.py --rows avq,avq-maze  # some rows only
    python scripts/ablation_avq.py --holdout --rows "avq,no cycle split"
        # more data: seeds 100-159 and 200-259, mazes 100-139 and 200-239 (--check: 300-399, 300-359)
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed

from avq.envs import random_layout
from avq.reproduce import train_maze_run

#: The Sarsa(λ) agent that ``avq`` was on the grid maze until the planner with merging replaced it: the maze
#: rules (``avq-maze``) with the cycle split and a decaying exploration rate. The rows switch one option from it.
SARSA_AVQ = {"cycle_split": True, "epsilon": 0.2, "epsilon_decay": 0.995, "epsilon_min": 0.01}


def sarsa_avq(**changes) -> tuple[str, dict]:
    """A row of SARSA_AVQ with ``changes``."""
    return "avq-maze", {**SARSA_AVQ, **changes}


#: row label -> (registered agent, overrides); "avq" is SARSA_AVQ.
ROWS: dict[str, tuple[str, dict]] = {
    "avq": sarsa_avq(),
    "no cycle split": sarsa_avq(cycle_split=False),
    "no collision split": sarsa_avq(collision_split=False),
    "neither split": sarsa_avq(cycle_split=False, collision_split=False),
    "merge pairs: mutual (the paper)": sarsa_avq(merge_pairs="mutual"),
    "merge guard: same action": sarsa_avq(merge_same_action=True),
    "merge guard: 2 episodes": sarsa_avq(merge_age=2),
    "no merging": sarsa_avq(merge_every=0),
    "no cell cap": sarsa_avq(max_cells=10_000),
    "make room at the cap": sarsa_avq(make_room=True),
    "constant epsilon 0.05 (no schedule)": sarsa_avq(epsilon=0.05, epsilon_decay=1.0, epsilon_min=0.0),
    "constant epsilon 0.05 and no cycle split (avq-maze)": sarsa_avq(
        epsilon=0.05, epsilon_decay=1.0, epsilon_min=0.0, cycle_split=False
    ),
    "alpha 0.5 decaying by 0.998 to 0.05": sarsa_avq(alpha_decay=0.998, alpha_min=0.05),
    "vectors adapt: rate 0.01": sarsa_avq(adapt_rate=0.01),
    "vectors adapt: rate 0.05": sarsa_avq(adapt_rate=0.05),
    "pruning: after 10 episodes": sarsa_avq(prune_after=10),
    "pruning: after 50 episodes": sarsa_avq(prune_after=50),
    "count-based bonus 0.5": sarsa_avq(explore_bonus=0.5),
    "count-based bonus 1": sarsa_avq(explore_bonus=1.0),
    "count-based bonus 5": sarsa_avq(explore_bonus=5.0),
    "count-based bonus 5 with q_init 0": sarsa_avq(explore_bonus=5.0, q_init=0.0),
    "no optimism: q_init 0": sarsa_avq(q_init=0.0),
    "more optimism: q_init 20": sarsa_avq(q_init=20.0),
    "optimism only: epsilon 0": sarsa_avq(epsilon=0.0, epsilon_decay=1.0, epsilon_min=0.0),
    "avq-paper": ("avq-paper", {}),
    "tabular": ("tabular", {}),
}
SEEDS = range(30)
MAZES = range(20)
#: Fresh data (--holdout): 120 more seeds of lau2002 and 80 more generated mazes.
HOLDOUT_SEEDS = [*range(100, 160), *range(200, 260)]
HOLDOUT_MAZES = [*range(100, 140), *range(200, 240)]
#: A last check (--check): data used for nothing else, 100 seeds and 60 mazes.
CHECK_SEEDS, CHECK_MAZES = range(300, 400), range(300, 360)


def one(row: str, agent: str, overrides: dict, where: str, seed: int, maze: int | None) -> dict:
    layout = "lau2002" if maze is None else random_layout(13, 13, 0.2, seed=maze)
    r = train_maze_run(agent, layout, seed, 1000, overrides=overrides)
    return {
        "row": row,
        "where": where,
        "seed": seed,
        "maze": "" if maze is None else maze,
        "success": round(r.success_rate, 4),
        "cells": r.n_cells,
        "path_ratio": "" if r.path_ratio is None else round(r.path_ratio, 4),
        "env_steps": r.env_steps,
    }


def _all_three(r: dict) -> bool:
    return r["success"] >= 0.95 and r["path_ratio"] != "" and r["path_ratio"] <= 1.15 and r["cells"] <= 30


def summarize(rs: list[dict]) -> str:
    succ = np.array([r["success"] for r in rs])
    ratios = [r["path_ratio"] for r in rs if r["path_ratio"] != ""]
    cells = [r["cells"] for r in rs]
    return (
        f"{succ.mean():.3f} ({succ.min():.2f}) | {sum(succ >= 0.95)}/{len(rs)} | "
        f"{int(np.median(cells))} [{min(cells)}–{max(cells)}] | {np.mean(ratios):.2f} ({max(ratios):.2f}) | "
        f"{np.mean([r['env_steps'] for r in rs]):,.0f} | **{sum(map(_all_three, rs))}/{len(rs)}**"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", default=",".join(ROWS), help="comma-separated row labels (default: all)")
    assert not any("," in row for row in ROWS)
    ap.add_argument("--jobs", type=int, default=-1)
    ap.add_argument("--check", action="store_true", help="lau2002 seeds 300-399 and mazes 300-359 instead")
    ap.add_argument(
        "--holdout",
        action="store_true",
        help="lau2002 seeds 100-159, 200-259 and generated mazes 100-139, 200-239 instead",
    )
    ap.add_argument(
        "--csv",
        default=None,
        help="where to write every run (default: docs/data/ablation_avq.csv for all rows, none for some)",
    )
    args = ap.parse_args()
    rows = [r.strip() for r in args.rows.split(",")]
    unknown = [r for r in rows if r not in ROWS]
    if unknown:
        ap.error(f"unknown row {unknown[0]!r}; rows: {', '.join(ROWS)}")
    seeds, mazes = (
        (CHECK_SEEDS, CHECK_MAZES) if args.check else (HOLDOUT_SEEDS, HOLDOUT_MAZES) if args.holdout else (SEEDS, MAZES)
    )
    jobs = [(row, *ROWS[row], "lau2002", s, None) for row in rows for s in seeds]
    jobs += [(row, *ROWS[row], "generated", 0, m) for row in rows for m in mazes]
    results = Parallel(n_jobs=args.jobs)(delayed(one)(*job) for job in jobs)
    csv_path = args.csv or (
        "docs/data/ablation_avq.csv" if rows == list(ROWS) and not (args.holdout or args.check) else None
    )
    if csv_path:
        Path(csv_path).parent.mkdir(parents=True, exist_ok=True)
        with open(csv_path, "w", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=list(results[0]))
            writer.writeheader()
            writer.writerows(results)
    head = (
        "| success, mean (worst) | ≥ 95% | cells, median [range] | path ratio, mean (worst) | env steps "
        "| all three |\n|---|---|---|---|---|---|---|"
    )
    tables = (
        ("lau2002, seeds 0-9", lambda r: r["where"] == "lau2002" and r["seed"] < 10),
        ("lau2002, seeds 0-29", lambda r: r["where"] == "lau2002"),
        ("20 generated mazes", lambda r: r["where"] == "generated"),
    )
    if args.holdout or args.check:
        tables = (
            (f"lau2002, {len(seeds)} seeds", lambda r: r["where"] == "lau2002"),
            (f"{len(mazes)} generated mazes", lambda r: r["where"] == "generated"),
        )
    for title, pick in tables:
        print(f"\n{title}\n\n| configuration {head}")
        for row in rows:
            print(f"| {row} | {summarize([r for r in results if r['row'] == row and pick(r)])} |")
    if csv_path:
        print(f"\nwrote {csv_path}")


if __name__ == "__main__":
    main()
