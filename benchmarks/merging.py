"""Merging under the model (``avq-plan``'s ``rho``): the paper's protocol on ``lau2002`` and the refined mazes.

Two studies, each a CSV under ``docs/data/`` and a table printed:

* ``--protocol``: ``avq reproduce``'s protocol (``lau2002``, 1000 trials, then the greedy policy walked
  from every start) for each variant, over a set of seeds; per seed the cells, the greedy success and the
  path ratio, and whether the seed meets all three of: success >= 95%, cells <= 30, path ratio <= 1.15.
* ``--resolution``, ``--robot``, ``--generated``: env steps to 95% greedy success, and the cells then, on
  ``lau2002`` refined k x k, on ``avq/RobotMaze-v0`` with finer moves, and on generated mazes of growing
  side (``--slip 0.1``: slippery), as ``benchmarks/scaling.py`` measures its agents on the same mazes.
* ``--new``: env steps to 95% on mazes never used to choose anything (two made by hand, one of corridors one
  square wide and one without border walls, and generated layouts of other seeds than the tuning ones'), for
  agents by name (``--agents``: ``avq`` beside the baselines), deterministic or with ``--slip``.

Variants (``--variants``, names below) are ``avq-plan`` on the maze with the overrides listed; seeds are
chosen with ``--seeds`` (``0-29``: the seeds the variants were chosen on; ``100-199`` and ``200-299``: held out).

    python benchmarks/merging.py --protocol --seeds 0-29
    python benchmarks/merging.py --protocol --seeds 100-199 --variants no-merge merge merge+cycle+radius
    python benchmarks/merging.py --protocol --seeds 200-299 --variants merge merge+cycle+radius
    python benchmarks/merging.py --resolution --seeds 0-4 --variants no-merge merge merge+cycle+radius
    python benchmarks/merging.py --robot --seeds 0-9 --variants merge merge+cycle+radius
    python benchmarks/merging.py --robot --seeds 10-19 --variants no-merge merge merge+cycle+radius
    python benchmarks/merging.py --generated --seeds 0-4 --variants merge merge+cycle+radius
    python benchmarks/merging.py --new --seeds 0-4 --agents avq tabular-ps tiles
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
from joblib import Parallel, delayed

sys.path.insert(0, str(Path(__file__).parent))
from scaling import learn_until, maze_factory  # noqa: E402

import avq  # noqa: E402
from avq.envs import parse_layout, random_layout  # noqa: E402
from avq.reproduce import train_maze_run  # noqa: E402

#: Each variant's overrides of ``avq-plan``'s maze entry.
VARIANTS = {
    "no-merge": {},
    "cycle": {"cycle_split": True},
    "merge-profiles": {"rho": 25.0, "merge_same_action": False},
    "merge": {"rho": 25.0},
    "merge+cycle": {"rho": 25.0, "cycle_split": True},
    "merge+radius": {"rho": 25.0, "known_radius": 0.3},
    "merge+cycle+radius": {"rho": 25.0, "cycle_split": True, "known_radius": 0.3},
    # The ablation of merge+radius (``avq`` on the grid maze): one rule off or changed at a time.
    "radius": {"known_radius": 0.3},
    "merge+radius, no collision growth": {"rho": 25.0, "known_radius": 0.3, "collision_growth": False},
    "merge+radius, no outcome split": {"rho": 25.0, "known_radius": 0.3, "outcome_split": False},
    "merge+radius, no optimism": {"rho": 25.0, "known_radius": 0.3, "v_opt": -10_000.0, "epsilon": 0.1},
    "merge+radius, known after 3": {"rho": 25.0, "known_radius": 0.3, "known_after": 3},
    # More merging on the refined mazes (ρ is a mean square of returns, which grow k times longer).
    **{f"merge+radius, rho {r}": {"rho": float(r), "known_radius": 0.3} for r in (200, 800, 1600)},
}
#: ``--new``: mazes never used to choose a setting. Two made by hand (47 and 89 squares), and generated
#: layouts of the tuning mazes' sides with other seeds (the tuning mazes are ``seed=1000 + side``).
NEW_MAZES = {
    "corridors": [
        "#############",
        "#S#.......#G#",
        "#.#.#####.#.#",
        "#.#.#...#.#.#",
        "#.#.#.#.#.#.#",
        "#...#.#...#.#",
        "#####.#####.#",
        "#...........#",
        "#############",
    ],
    "no-border": [
        "S...........",
        "............",
        "..#######...",
        "........#...",
        "........#.#.",
        "..#.....#.#G",
        "..#.....###.",
        "..#.........",
        "..#.........",
    ],
    **{f"held-out-{side}": random_layout(side, side, 0.2, seed=3000 + side) for side in (22, 42, 62)},
}
NEW_FIELDS = ("agent", "maze", "squares", "slip", "seed", "reached", "env_steps", "cells")
#: ``--new``: what each agent gets beyond its defaults here (no budget of cells: the runs measure growth).
UNCAPPED = {"max_cells": 1_000_000}
NEW_AGENTS = {"avq": UNCAPPED, "avq-plan": UNCAPPED, "tabular-ps": {}, "tiles": {}, "avq-maze": UNCAPPED}
PROTOCOL_FIELDS = ("variant", "seed", "cells", "success", "path_ratio", "env_steps", "meets")
STEPS_FIELDS = ("variant", "size", "seed", "reached", "env_steps", "cells")
#: Each family of mazes: its sizes (k, move or side) and its default budget of env steps.
FAMILIES = {
    "resolution": ((1, 2, 4, 8), 400_000),
    "robot": ((0.25, 0.125), 1_000_000),
    "generated": ((12, 22, 42, 62, 92), 1_000_000),
}


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


def steps_row(family: str, variant: str, size: float, seed: int, budget: int, slip: float) -> dict:
    make, _, limit = maze_factory(family, size, slip)
    agent = avq.make_agent("avq-plan", make(), seed=seed, **{"max_cells": 1_000_000, **VARIANTS[variant]})
    walks = make()
    if slip:
        walks.reset(seed=10_000 + seed)  # (the walks slip too: seeded, as benchmarks/scaling.py)
    reached, _, _ = learn_until(agent, walks, budget, 0.95, max_steps=limit)
    return dict(
        variant=variant, size=size, seed=seed, reached=reached, env_steps=agent.num_timesteps, cells=agent.n_cells
    )


def new_agent(name: str) -> tuple[str, dict]:
    """``--new``'s agent ``name``: a registered agent of NEW_AGENTS, or a variant (``avq-plan`` with its overrides)."""
    if name in NEW_AGENTS:
        return name, NEW_AGENTS[name]
    return "avq-plan", {**UNCAPPED, **VARIANTS[name]}


def new_row(agent_name: str, maze: str, seed: int, budget: int, slip: float) -> dict:
    rows = NEW_MAZES[maze]
    limit = 4 * (len(rows) + len(rows[0]))
    make = lambda: gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=limit, slip=slip)  # noqa: E731
    name, overrides = new_agent(agent_name)
    agent = avq.make_agent(name, make(), seed=seed, **overrides)
    walks = make()
    if slip:
        walks.reset(seed=10_000 + seed)
    reached, _, _ = learn_until(agent, walks, budget, 0.95, max_steps=limit)
    return dict(
        agent=agent_name,
        maze=maze,
        squares=parse_layout(rows).n_states,
        slip=slip,
        seed=seed,
        reached=reached,
        env_steps=agent.num_timesteps,
        cells=agent.n_cells,
    )


def new_study(args: argparse.Namespace, seeds: list[int]) -> None:
    mazes = args.mazes or list(NEW_MAZES)
    jobs = [
        delayed(new_row)(a, m, s, args.budget or 1_000_000, args.slip)
        for a in args.agents
        for m in mazes
        for s in seeds
    ]
    rows = run_and_write(jobs, args, "new", NEW_FIELDS, keep_others="agent")  # (an agent can be run again alone)
    print("| maze (squares) | " + " | ".join(f"`{a}`" for a in args.agents) + " |")
    print("|---" * (len(args.agents) + 1) + "|")
    for m in mazes:
        cells = []
        for a in args.agents:
            rs = [r for r in rows if r["agent"] == a and r["maze"] == m]
            st = [r["env_steps"] for r in rs]
            n = sum(r["reached"] for r in rs)
            miss = "" if n == len(rs) else f" ({n} of {len(rs)})"
            cells.append(
                f"{np.median(st):,.0f} [{min(st):,}-{max(st):,}]{miss}, {np.median([r['cells'] for r in rs]):.0f}"
            )
        print(f"| {m} ({rs[0]['squares']}) | " + " | ".join(cells) + " |")


def seeds_of(text: str) -> list[int]:
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def write(path: Path, fields: tuple, rows: list[dict]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)


def run_and_write(jobs: list, args: argparse.Namespace, study: str, fields: tuple, keep_others: str = "") -> list[dict]:
    """Run ``jobs`` on ``args.jobs`` processes and write their rows to ``merging_STUDY[_slipP]_seedsS.csv``; with
    ``keep_others`` (a field), the file's rows whose value of it none of the new rows has are kept."""
    rows = Parallel(n_jobs=args.jobs)(jobs)
    slip = f"_slip{args.slip:g}" if args.slip else ""
    path = Path(args.out) / f"merging_{study}{slip}_seeds{args.seeds}.csv"
    kept = []
    if keep_others and path.exists():
        ran = {str(r[keep_others]) for r in rows}
        kept = [r for r in csv.DictReader(path.open()) if r[keep_others] not in ran]
    write(path, fields, kept + rows)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--protocol", action="store_true")
    for family in FAMILIES:
        ap.add_argument(f"--{family}", action="store_true")
    ap.add_argument("--new", action="store_true")
    ap.add_argument("--slip", type=float, default=0.0, help="--generated, --new: the slip probability")
    ap.add_argument(
        "--agents",
        nargs="+",
        default=["avq", "tabular-ps", "tiles"],
        choices=[*NEW_AGENTS, *VARIANTS],
        help="--new: agents by name, or variants (default: avq tabular-ps tiles)",
    )
    ap.add_argument("--mazes", nargs="+", default=None, choices=list(NEW_MAZES), help="--new: some mazes only")
    ap.add_argument("--sizes", type=float, nargs="+", default=None, help="instead of the family's")
    ap.add_argument("--seeds", default="0-29")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--budget", type=int, default=None, help="env steps per run (default: the family's)")
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
    if args.new:
        new_study(args, seeds)
    for family, (default_sizes, default_budget) in FAMILIES.items():
        if getattr(args, family):
            steps_study(family, args, seeds, args.sizes or default_sizes, args.budget or default_budget)


def steps_study(family: str, args: argparse.Namespace, seeds: list[int], sizes, budget: int) -> None:
    jobs = [
        delayed(steps_row)(family, v, size, s, budget, args.slip)
        for v in args.variants
        for size in sizes
        for s in seeds
    ]
    rows = run_and_write(jobs, args, family, STEPS_FIELDS)
    print(
        f"| variant | {'k' if family == 'resolution' else 'move' if family == 'robot' else 'side'} | reached 95% | "
        "env steps median [range] | cells median [range] |"
    )
    print("|---|---|---|---|---|")
    for v in args.variants:
        for size in sizes:
            rs = [r for r in rows if r["variant"] == v and r["size"] == size]
            st = [r["env_steps"] for r in rs]
            c = [r["cells"] for r in rs]
            print(
                f"| {v} | {size:g} | {sum(r['reached'] for r in rs)} of {len(rs)} | {np.median(st):,.0f} "
                f"[{min(st):,}-{max(st):,}] | {np.median(c):.0f} [{min(c)}-{max(c)}] |"
            )


if __name__ == "__main__":
    main()
