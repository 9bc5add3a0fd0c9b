"""Wall time of one sweep (8 configurations x 10 seeds on RobotMaze) on each backend.

The reference, measured in the same run, is the same trials one after another in
this process (``backend="local", jobs=1``). Then the local backend with one
worker per core (joblib processes), a local Ray cluster and a local Dask cluster,
each started and stopped inside the timing, as a user's ``avq sweep`` would.
Every backend must give the same results table (checked; wall times aside).

    python benchmarks/sweep_backends.py            # 80 trials of 300 episodes
    python benchmarks/sweep_backends.py --quick    # 16 trials of 30 episodes
"""

from __future__ import annotations

import argparse
import csv
import os
import tempfile
import time
from pathlib import Path

import avq
from avq.sweep import run_sweep


def config(episodes: int, seeds: int, grid: dict) -> dict:
    # The general Sarsa(λ) defaults (as measured in docs/results/general-defaults.md), not the maze rules avq takes on RobotMaze.
    general = {**avq.AGENTS["avq-sarsa"][1], "collision_split": False, "merge_pairs": "mutual", "max_cells": 10_000}
    params = {k: v for k, v in general.items() if k not in grid}
    return {
        "env": "avq/RobotMaze-v0",
        "agents": ["avq-sarsa"],
        "grid": grid,
        "params": params,
        "seeds": seeds,
        "episodes": episodes,
        "eval_episodes": 5,
        "save_models": True,
    }


def table(out: Path) -> list[dict[str, str]]:
    with open(out / "results.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        row.pop("wall_s")
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    grid = {"alpha": [0.1, 0.3], "epsilon": [0.05, 0.1], "d_min": [0.05, 0.1]}
    cfg = config(30, 2, grid) if args.quick else config(300, 10, grid)
    n_trials = 8 * cfg["seeds"]
    print(
        f"machine: {os.cpu_count()} cores; avq {avq.__version__}; {n_trials} trials of {cfg['episodes']} "
        f"episodes on RobotMaze; {args.jobs} workers"
    )
    # Warm the compilation cache so that no backend pays for compiling.
    with tempfile.TemporaryDirectory() as tmp:
        run_sweep(config(2, 1, {"alpha": [0.1]}), Path(tmp) / "warm", jobs=1, progress=False)
    runs = [
        ("one process, one after another", "local", 1),
        ("local (joblib processes)", "local", args.jobs),
        ("ray (local cluster started)", "ray", args.jobs),
        ("dask (LocalCluster started)", "dask", args.jobs),
    ]
    times: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        reference = None
        for label, backend, jobs in runs:
            out = Path(tmp) / label.split()[0]
            t = time.perf_counter()
            try:
                run_sweep(cfg, out, backend=backend, jobs=jobs, progress=False)
            except ValueError as exc:  # a backend that is not installed
                print(f"   {label}: skipped ({exc})")
                continue
            times[label] = time.perf_counter() - t
            rows = table(out)
            if reference is None:
                reference = rows
            same = rows == reference
            with open(out / "results.csv", encoding="utf-8") as f:
                trial_s = sum(float(r["wall_s"]) for r in csv.DictReader(f))
            print(
                f"   {label:<32} {times[label]:>7.1f} s   (sum of trial times {trial_s:.1f} s)   "
                f"results {'identical' if same else 'DIFFERENT'}"
            )
    base = times.get("one process, one after another")
    local = times.get("local (joblib processes)")
    if base and local:
        print(f"\nspeed-up of local over one process: {base / local:.2f}x on {args.jobs} workers")
    for label in ("ray (local cluster started)", "dask (LocalCluster started)"):
        if label in times and local:
            print(f"{label}: {times[label] - local:+.1f} s against local ({times[label] / local:.2f}x)")


if __name__ == "__main__":
    main()
