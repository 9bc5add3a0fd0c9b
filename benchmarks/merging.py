"""Merging under the model (``avq-plan``'s ``rho``): the paper's protocol on ``lau2002`` and the refined mazes.

Two studies, each a CSV under ``docs/data/`` and a table printed:

* ``--protocol``: ``avq reproduce``'s protocol (``lau2002``, 1000 trials, then the greedy policy walked
  from every start) for each variant, over a set of seeds; per seed the cells, the greedy success and the
  path ratio, and whether the seed meets all three of: success >= 95%, cells <= 30, path ratio <= 1.15.
* ``--resolution``: env steps to 95% greedy success on ``lau2002`` refined k x k (as
  ``benchmarks/scaling.py --resolution``), and the cells then.

Variants (``--variants``, names below) are ``avq-plan`` on the maze with the overrides listed; seeds are
chosen with ``--seeds`` (``0-29``: the seeds the variants were chosen on; ``100-199`` and ``200-299``: held out).

    python benchmarks/merging.py --protocol --seeds 0-29
    python benchmarks/merging.py --protocol --seeds 100-199 --variants no-merge merge+cycle+radius
    python benchmarks/merging.py --resolution --seeds 0-4 --variants no-merge merge+cycle+radius
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed

sys.path.insert(0, str(Path(__file__).parent))
from scaling import learn_until, maze_factory  # noqa: E402

import avq  # noqa: E402
from avq.reproduce import train_maze_run  # noqa: E402

#: Each variant's overrides of ``avq-plan``'s maze entry.
VARIANTS = {
    "no-merge": {},
    "merge-profiles": {"rho": 25.0, "merge_same_action": False},
    "merge": {"rho": 25.0},
    "merge+cycle": {"rho": 25.0, "cycle_split": True},
    "merge+radius": {"rho": 25.0, "known_radius": 0.3},
    "merge+cycle+radius": {"rho": 25.0, "cycle_split": True, "known_radius": 0.3},
}
PROTOCOL_FIELDS = ("variant", "seed", "cells", "success", "path_ratio", "env_steps", "meets")
RESOLUTION_FIELDS = ("variant", "k", "seed", "reached", "env_steps", "cells")


def protocol_row(variant: str, seed: int) -> dict:
    r = train_maze_run("avq-plan", "lau2002", seed, 1000, overrides=VARIANTS[variant])
    ratio = r.path_ratio if r.path_ratio is not None else float("inf")
    meets = r.success_rate >= 0.95 and r.n_cells <= 30 and ratio <= 1.15
    return dict(
        variant=variant,
        seed=seed,
        cells=r.n_cells,
        success=round(r.success_rate, 4),
        path_ratio=round(ratio, 4),
        env_steps=r.env_steps,
        meets=meets,
    )


def resolution_row(variant: str, k: int, seed: int, budget: int) -> dict:
    make, _, limit = maze_factory("resolution", k, 0.0)
    agent = avq.make_agent("avq-plan", make(), seed=seed, **{"max_cells": 1_000_000, **VARIANTS[variant]})
    reached, _, _ = learn_until(agent, make(), budget, 0.95, max_steps=limit)
    return dict(variant=variant, k=k, seed=seed, reached=reached, env_steps=agent.num_timesteps, cells=agent.n_cells)


def seeds_of(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def write(path: Path, fields: tuple, rows: list[dict]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--protocol", action="store_true")
    ap.add_argument("--resolution", action="store_true")
    ap.add_argument("--seeds", default="0-29")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--k", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--budget", type=int, default=400_000)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs/data")
    args = ap.parse_args()
    seeds = seeds_of(args.seeds)
    if args.protocol:
        jobs = [delayed(protocol_row)(v, s) for v in args.variants for s in seeds]
        rows = Parallel(n_jobs=args.jobs)(jobs)
        write(Path(args.out) / f"merging_protocol_seeds{args.seeds}.csv", PROTOCOL_FIELDS, rows)
        print("| variant | seeds meeting all three | cells median [range] | worst success | path ratio median, worst |")
        print("|---|---|---|---|---|")
        for v in args.variants:
            rs = [r for r in rows if r["variant"] == v]
            c = [r["cells"] for r in rs]
            q = [r["path_ratio"] for r in rs]
            print(
                f"| {v} | {sum(r['meets'] for r in rs)} of {len(rs)} | {np.median(c):.0f} [{min(c)}-{max(c)}] | "
                f"{min(r['success'] for r in rs):.0%} | {np.median(q):.3f}, {max(q):.2f} |"
            )
    if args.resolution:
        jobs = [delayed(resolution_row)(v, k, s, args.budget) for v in args.variants for k in args.k for s in seeds]
        rows = Parallel(n_jobs=args.jobs)(jobs)
        write(Path(args.out) / "merging_resolution.csv", RESOLUTION_FIELDS, rows)
        print("| variant | k | reached 95% | env steps median [range] | cells median [range] |")
        print("|---|---|---|---|---|")
        for v in args.variants:
            for k in args.k:
                rs = [r for r in rows if r["variant"] == v and r["k"] == k]
                st = [r["env_steps"] for r in rs]
                c = [r["cells"] for r in rs]
                print(
                    f"| {v} | {k} | {sum(r['reached'] for r in rs)} of {len(rs)} | {np.median(st):,.0f} "
                    f"[{min(st):,}-{max(st):,}] | {np.median(c):.0f} [{min(c)}-{max(c)}] |"
                )


if __name__ == "__main__":
    main()
