"""Environment steps to a reliable greedy policy, against the number of states of a maze.

Each agent learns in chunks of episodes (1, 2, 4, ... up to 200); after every chunk its greedy
policy is walked from every start (``avq.evaluate_maze``). The figure is the number of environment
steps at the first evaluation with at least 95% success, and the cells in use then. A run that does
not get there within its step budget is censored (the budget is reported instead, marked ``>``).

Three families of mazes, each with its own CSV and figure:

* generated mazes (``avq.envs.random_layout``, wall density 0.2) of growing size, episodes limited to
  ``4 * (width + height)`` steps; ``--slip 0.1`` makes every move slip sideways with probability 0.1;
* ``--resolution``: the paper's maze ``lau2002`` refined ``k`` x ``k`` (``avq.envs.refine_layout``,
  k = 1, 2, 4, 8: 98 to 6,272 squares), the same structure at a finer and finer resolution;
* ``--robot``: ``avq/RobotMaze-v0`` on ``lau2002`` with finer and finer moves. Its positions lie on a
  lattice of the move from a random start in each square, so full resolution is one bin per move
  step: ``grid-ps`` (the model-based planner of ``tabular-ps`` on those bins) and ``grid`` (Sarsa(λ)).

The AVQ agents' cells are not capped here (``max_cells`` 1,000,000), so that their number is measured.

    python benchmarks/scaling.py                        # generated mazes, sides 12-92, 5 seeds
    python benchmarks/scaling.py --slip 0.1             # the same, slippery
    python benchmarks/scaling.py --resolution           # lau2002 refined k x k
    python benchmarks/scaling.py --robot                # RobotMaze, moves 0.5, 0.25, 0.125
    python benchmarks/scaling.py --agents avq-plan      # rerun one agent, keep the others' rows in the CSV
    python benchmarks/scaling.py --quick                # the two smallest sizes, 2 seeds
"""

from __future__ import annotations

import argparse
import csv
import os
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from joblib import Parallel, delayed

import avq
from avq.envs import parse_layout, random_layout, refine_layout

#: Agents per family, with the overrides they get here.
UNCAPPED = {"max_cells": 1_000_000}
MAZE_AGENTS = {
    "avq-plan": UNCAPPED,
    "tabular-ps": {},
    "avq": UNCAPPED,
    "avq-maze": UNCAPPED,
    "avq-paper": {},
    "tabular": {},
    "tiles": {},
}
ROBOT_AGENTS = {"avq-plan": UNCAPPED, "grid-ps": {}, "avq": UNCAPPED, "grid": {}, "tiles": {}}
FAMILIES = {
    "generated": dict(
        sizes=(12, 22, 42, 62, 92),
        quick=(12, 22),
        seeds=5,
        budget=3_000_000,
        agents=MAZE_AGENTS,
        size="side",
        csv="docs/data/scaling.csv",
        figure="docs/figures/scaling.png",
    ),
    "resolution": dict(
        sizes=(1, 2, 4, 8),
        quick=(1, 2),
        seeds=5,
        budget=3_000_000,
        agents=MAZE_AGENTS,
        size="k",
        csv="docs/data/scaling_resolution.csv",
        figure="docs/figures/scaling_resolution.png",
    ),
    "robot": dict(
        sizes=(0.5, 0.25, 0.125),
        quick=(0.5,),
        seeds=3,
        budget=1_000_000,
        agents=ROBOT_AGENTS,
        size="move",
        csv="docs/data/scaling_robot.csv",
        figure="docs/figures/scaling_robot.png",
    ),
}
FIELDS = ("agent", "size", "states", "slip", "seed", "reached", "env_steps", "cells", "success", "backups", "wall_s")


def learn_until(
    agent, eval_env, budget: int, target: float, chunk: int = 1, max_chunk: int = 200, max_steps: int | None = None
) -> tuple[bool, float, float]:
    """Learn in chunks of episodes (doubling up to ``max_chunk``) until the greedy policy succeeds from
    ``target`` of the starts or ``budget`` env steps are spent: ``(reached, success, wall seconds)``."""
    t0 = time.perf_counter()
    success = 0.0
    while agent.num_timesteps < budget:
        agent.learn(total_episodes=chunk)
        success = avq.evaluate_maze(agent, eval_env, max_steps=max_steps)["success_rate"]
        if success >= target:
            return True, success, round(time.perf_counter() - t0, 2)
        chunk = min(2 * chunk, max_chunk)
    return False, success, round(time.perf_counter() - t0, 2)


def maze_factory(family: str, size: float, slip: float):
    """``(make, states, step limit or None)`` for one maze of a family."""
    if family == "robot":
        make = lambda: gym.make("avq/RobotMaze-v0", move=size)  # noqa: E731
        return make, round(98 / size**2), None
    rows = (
        random_layout(int(size), int(size), 0.2, seed=1000 + int(size))
        if family == "generated"
        else refine_layout("lau2002", int(size))
    )
    limit = 4 * (len(rows) + len(rows[0]))
    make = lambda: gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=limit, slip=slip)  # noqa: E731
    return make, parse_layout(rows).n_states, limit


def steps_to_success(family: str, name: str, size: float, seed: int, budget: int, slip: float) -> dict:
    make, states, limit = maze_factory(family, size, slip)
    overrides = dict(FAMILIES[family]["agents"][name])
    if family == "robot" and name in ("grid", "grid-ps"):
        base = make().unwrapped
        overrides["bins"] = [round(base.layout.width / size), round(base.layout.height / size)]
    agent = avq.make_agent(name, make(), seed=seed, **overrides)
    eval_env = make()
    if slip:
        eval_env.reset(seed=10_000 + seed)  # the walks slip too: seeded, for repeatable figures
    reached, success, wall = learn_until(agent, eval_env, budget, 0.95, max_steps=limit)
    return {
        "agent": name,
        "size": size,
        "states": states,
        "slip": slip,
        "seed": seed,
        "reached": reached,
        "env_steps": int(agent.num_timesteps),
        "cells": int(agent.n_cells),
        "success": float(success),
        "backups": int(getattr(agent, "backups_", 0)),
        "wall_s": wall,
    }


def _read(path: str) -> list[dict]:
    if not Path(path).exists():
        return []
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    if not rows or "size" not in rows[0]:
        return []  # (a file of an older layout: rerun everything)
    for r in rows:
        r.update(
            size=float(r["size"]),
            states=int(r["states"]),
            slip=float(r["slip"]),
            seed=int(r["seed"]),
            reached=r["reached"] == "True",
            env_steps=int(r["env_steps"]),
            cells=int(r["cells"]),
            success=float(r["success"]),
            backups=int(r["backups"]),
            wall_s=float(r["wall_s"]),
        )
    return rows


def summarize(rows: list[dict], agents: list[str], sizes: tuple) -> dict:
    """``(agent, size) -> (states, median steps, reached, runs, median cells, (min, max) steps)``."""
    out = {}
    for size in sizes:
        for name in agents:
            rs = [r for r in rows if r["size"] == size and r["agent"] == name]
            if rs:
                steps = [r["env_steps"] for r in rs]
                out[(name, size)] = (
                    rs[0]["states"],
                    float(np.median(steps)),
                    sum(r["reached"] for r in rs),
                    len(rs),
                    float(np.median([r["cells"] for r in rs])),
                    (min(steps), max(steps)),
                )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    which = ap.add_mutually_exclusive_group()
    which.add_argument("--resolution", action="store_true", help="lau2002 refined k x k (see above)")
    which.add_argument("--robot", action="store_true", help="RobotMaze with finer moves (see above)")
    ap.add_argument("--slip", type=float, default=0.0, help="slip probability of the grid mazes (default 0)")
    ap.add_argument("--quick", action="store_true", help="the two smallest sizes, 2 seeds")
    ap.add_argument("--sizes", default=None, help="comma-separated sizes (sides, k or moves) instead of the family's")
    ap.add_argument("--seeds", type=int, default=None)
    ap.add_argument("--budget", type=int, default=None, help="env steps per run before giving up")
    ap.add_argument("--agents", default=None, help="comma-separated agents to run (default: all of the family)")
    ap.add_argument("--jobs", type=int, default=-1, help="parallel runs (default: one per core)")
    ap.add_argument("--plot", action="store_true", help="only the figure and the table, from the family's CSV")
    args = ap.parse_args()
    family = "resolution" if args.resolution else "robot" if args.robot else "generated"
    fam = FAMILIES[family]
    if args.slip and family == "robot":
        ap.error("--slip applies to the grid mazes only")
    names = [n.strip() for n in args.agents.split(",")] if args.agents else list(fam["agents"])
    if any(n not in fam["agents"] for n in names):
        ap.error(f"--agents: choose from {', '.join(fam['agents'])}")
    sizes = fam["quick"] if args.quick else fam["sizes"]
    if args.sizes:
        sizes = tuple(type(fam["sizes"][0])(v) for v in args.sizes.split(","))
    seeds = args.seeds or (2 if args.quick else fam["seeds"])
    budget = args.budget or fam["budget"]
    suffix = f"_slip{args.slip:g}" if args.slip else ""
    csv_path = fam["csv"].replace(".csv", suffix + ".csv")
    figure = fam["figure"].replace(".png", suffix + ".png")
    if args.plot:
        names = []  # (run nothing: every row of the CSV is kept)
    jobs = [(name, size, seed) for size in sizes for name in names for seed in range(seeds)]
    if jobs:
        print(
            f"{len(jobs)} runs ({family}{', slip ' + str(args.slip) if args.slip else ''}) on {os.cpu_count()} "
            f"cores: {fam['size']} {sizes}, {seeds} seeds, budget {budget:,} steps"
        )
    new = Parallel(n_jobs=args.jobs)(
        delayed(steps_to_success)(family, n, s, sd, budget, args.slip) for n, s, sd in jobs
    )
    kept = [
        r
        for r in _read(csv_path)
        if r["agent"] not in names and r["agent"] in fam["agents"] and r["size"] in sizes and r["seed"] < seeds
    ]
    rows = kept + new
    # The agents with runs at every size (kept rows from a run over other sizes are left out).
    present = [n for n in fam["agents"] if all(any(r["agent"] == n and r["size"] == s for r in rows) for s in sizes)]
    rows = [r for r in rows if r["agent"] in present]
    if args.plot and not present:
        ap.error(f"--plot: no runs of {', '.join(map(format, sizes))} in {csv_path}; run the study first")
    if not args.plot:
        Path(csv_path).parent.mkdir(parents=True, exist_ok=True)
        with open(csv_path, "w", newline="", encoding="utf-8") as f:
            writer = csv.DictWriter(f, fieldnames=FIELDS)
            writer.writeheader()
            writer.writerows(rows)
    summary = summarize(rows, present, sizes)
    print(
        f"\n{fam['size']:>6} {'states':>7} {'agent':<11} {'steps to 95%: median [range]':>34} {'reached':>8} "
        f"{'cells':>7}"
    )
    for size in sizes:
        for name in present:
            states, steps, got, n, cells, (lo, hi) = summary[(name, size)]
            mark = "" if got == n else ">"
            print(
                f"{size:>6g} {states:>7} {name:<11} {mark + format(int(steps), ','):>14} "
                f"[{lo:,}-{hi:,}]{'':>3} {got:>5}/{n} {int(cells):>7}"
            )
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for name in present:
        pts = [summary[(name, s)] for s in sizes]
        x = [p[0] for p in pts]
        axes[0].plot(x, [p[1] for p in pts], "o-", label=name)
        axes[1].plot(x, [p[4] for p in pts], "o-", label=name)
    labels = ("env steps to 95% greedy success (median)", "cells, states or features then (median)")
    states = [summary[(present[0], s)][0] for s in sizes]
    for ax, ylabel in zip(axes, labels):
        ax.set_xscale("log")
        # The measured sizes as the ticks, in plain numbers (a log axis over less than two decades otherwise
        # labels its minor ticks over each other).
        ax.set_xticks(states, [f"{int(v):,}" for v in states])
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_yscale("log")
        ax.set_xlabel({"robot": "lattice positions of the robot"}.get(family, "free squares of the maze"))
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    title = {
        "generated": "Generated mazes (wall density 0.2)",
        "resolution": "lau2002 refined k x k",
        "robot": "RobotMaze lau2002, finer moves",
    }[family]
    fig.suptitle(
        f"{title}{', slip ' + format(args.slip, 'g') if args.slip else ''}, {seeds} seeds; "
        f"runs that never reach 95% plot their budget ({budget:,})",
        fontsize=10,
    )
    fig.tight_layout()
    Path(figure).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(figure, dpi=130)
    print(f"\nwrote {figure}" if args.plot else f"\nwrote {csv_path} and {figure}")


if __name__ == "__main__":
    main()
