"""Environment steps to a reliable greedy policy, against the number of states of a maze.

For generated mazes (``avq.envs.random_layout``, wall density 0.2) of growing size,
each agent learns in chunks of episodes; after every chunk its greedy policy is
walked from every start (``avq.evaluate_maze``). The figure is the number of
environment steps at the first evaluation with at least 95% success, and the
cells in use then. A run that does not get there within its step budget counts
as censored (the budget is reported instead, marked ``>``).

Episodes are limited to ``4 * (width + height)`` steps. The AVQ agents get
``max_cells`` unbounded here, so that their cell count is measured, not capped.

    python benchmarks/scaling.py                 # sides 12, 22, 42, 62; 5 seeds (a few minutes)
    python benchmarks/scaling.py --quick         # sides 12 and 22; 2 seeds
    python benchmarks/scaling.py --agents avq    # rerun one agent, keep the others' rows in the CSV
    python benchmarks/scaling.py --robot         # RobotMaze lau2002 with finer and finer moves instead

With ``--robot``, the maze is ``avq/RobotMaze-v0`` on ``lau2002`` with ``move`` 0.5, 0.25 and
0.125 (the robot's positions lie on a lattice of that step: about 98 / move**2 of them), and
full resolution is ``grid`` with one bin per lattice step (``tabular`` would make a row for every
rounding of a float position). Budget 1 M steps, 3 seeds.
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
from avq.envs import parse_layout, random_layout

AGENTS = {"avq": {"max_cells": 1_000_000}, "avq-maze": {"max_cells": 1_000_000}, "avq-paper": {}, "tabular": {},
          "tiles": {}}


def steps_to_success(name: str, side: int, seed: int, budget: int, target: float = 0.95) -> dict:
    rows = random_layout(side, side, 0.2, seed=1000 + side)
    limit = 4 * (2 * side)
    make = lambda: gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=limit)
    agent = avq.make_agent(name, make(), seed=seed, **AGENTS[name])
    reached, success, wall = learn_until(agent, make(), budget, target, 10, 200, max_steps=limit)
    return {"agent": name, "side": side, "states": parse_layout(rows).n_states, "seed": seed,
            "reached": reached, "env_steps": int(agent.num_timesteps), "cells": int(agent.n_cells),
            "success": float(success), "wall_s": wall}


def learn_until(agent, eval_env, budget: int, target: float, chunk: int, max_chunk: int,
                max_steps: int | None = None) -> tuple[bool, float, float]:
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


ROBOT_AGENTS = ("avq", "grid", "tiles")


def robot_steps_to_success(name: str, move: float, seed: int, budget: int, target: float = 0.95) -> dict:
    make = lambda: gym.make("avq/RobotMaze-v0", move=move)
    base = make().unwrapped
    overrides = {"bins": [round(base.layout.width / move), round(base.layout.height / move)]} if name == "grid" else {}
    agent = avq.make_agent(name, make(), seed=seed, **overrides)
    reached, success, wall = learn_until(agent, make(), budget, target, 20, 400)
    return {"agent": name, "move": move, "positions": round(98 / move**2), "seed": seed, "reached": reached,
            "env_steps": int(agent.num_timesteps), "cells": int(agent.n_cells), "success": float(success),
            "wall_s": wall}


def robot_main(csv_path: str, seeds: int, budget: int) -> None:
    moves = (0.5, 0.25, 0.125)
    jobs = [(name, move, seed) for move in moves for name in ROBOT_AGENTS for seed in range(seeds)]
    print(f"{len(jobs)} RobotMaze runs: moves {moves}, {seeds} seeds, budget {budget} steps")
    rows = Parallel(n_jobs=-1)(delayed(robot_steps_to_success)(n, m, sd, budget) for n, m, sd in jobs)
    Path(csv_path).parent.mkdir(parents=True, exist_ok=True)
    with open(csv_path, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"\n{'move':>6} {'positions':>9} {'agent':<6} {'steps to 95% (median)':>22} {'reached':>8} "
          f"{'cells':>6} {'success then (median)':>22}")
    for move in moves:
        for name in ROBOT_AGENTS:
            rs = [r for r in rows if r["move"] == move and r["agent"] == name]
            got = sum(r["reached"] for r in rs)
            mark = "" if got == len(rs) else ">"
            print(f"{move:>6} {rs[0]['positions']:>9} {name:<6} "
                  f"{mark + format(int(np.median([r['env_steps'] for r in rs])), ','):>22} {got:>5}/{len(rs)} "
                  f"{int(np.median([r['cells'] for r in rs])):>6} {np.median([r['success'] for r in rs]):>22.2f}")
    print(f"\nwrote {csv_path}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--seeds", type=int, default=None)
    ap.add_argument("--budget", type=int, default=3_000_000, help="env steps per run before giving up")
    ap.add_argument("--csv", default="docs/data/scaling.csv")
    ap.add_argument("--figure", default="docs/figures/scaling.png")
    ap.add_argument("--agents", default=",".join(AGENTS), help="comma-separated agents to run (default: all)")
    ap.add_argument("--robot", action="store_true", help="RobotMaze with finer moves (see above)")
    args = ap.parse_args()
    if args.robot:
        robot_main("docs/data/scaling_robot.csv" if args.csv == "docs/data/scaling.csv" else args.csv,
                   args.seeds or 3, min(args.budget, 1_000_000))
        return
    names = [n.strip() for n in args.agents.split(",")]
    if any(n not in AGENTS for n in names):
        ap.error(f"--agents: choose from {', '.join(AGENTS)}")
    sides = (12, 22) if args.quick else (12, 22, 42, 62)
    seeds = args.seeds or (2 if args.quick else 5)
    jobs = [(name, side, seed) for side in sides for name in names for seed in range(seeds)]
    print(f"{len(jobs)} runs on {os.cpu_count()} cores: sides {sides}, {seeds} seeds, budget {args.budget} steps")
    rows = Parallel(n_jobs=-1)(delayed(steps_to_success)(n, s, sd, args.budget) for n, s, sd in jobs)
    if Path(args.csv).exists():  # keep the rows of the agents not run now
        with open(args.csv, newline="", encoding="utf-8") as f:
            kept = [r for r in csv.DictReader(f) if r["agent"] not in names and r["agent"] in AGENTS
                    and int(r["side"]) in sides and int(r["seed"]) < seeds]
        for r in kept:
            r.update(side=int(r["side"]), states=int(r["states"]), seed=int(r["seed"]), reached=r["reached"] == "True",
                     env_steps=int(r["env_steps"]), cells=int(r["cells"]), success=float(r["success"]),
                     wall_s=float(r["wall_s"]))
        rows = kept + rows
    # The agents with runs at every size (kept rows from a run over other sizes are left out).
    present = [n for n in AGENTS if all(any(r["agent"] == n and r["side"] == sd for r in rows) for sd in sides)]
    rows = [r for r in rows if r["agent"] in present]
    Path(args.csv).parent.mkdir(parents=True, exist_ok=True)
    with open(args.csv, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"\n{'states':>7} {'agent':<10} {'steps to 95% (median)':>22} {'reached':>8} {'cells':>7}")
    summary = {}
    for side in sides:
        for name in present:
            rs = [r for r in rows if r["side"] == side and r["agent"] == name]
            steps = np.median([r["env_steps"] for r in rs])
            got = sum(r["reached"] for r in rs)
            summary[(name, side)] = (rs[0]["states"], steps, got, len(rs))
            mark = "" if got == len(rs) else ">"
            print(f"{rs[0]['states']:>7} {name:<10} {mark + format(int(steps), ','):>22} {got:>5}/{len(rs)} "
                  f"{int(np.median([r['cells'] for r in rs])):>7}")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for name in present:
        pts = [summary[(name, s)] for s in sides]
        x = [p[0] for p in pts]
        axes[0].plot(x, [p[1] for p in pts], "o-", label=name)
        axes[1].plot(x, [np.median([r["cells"] for r in rows if r["side"] == s and r["agent"] == name])
                         for s in sides], "o-", label=name)
    for ax, ylabel in zip(axes, ("env steps to 95% greedy success (median)", "cells then (median)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("free squares of the maze")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"Generated mazes (wall density 0.2), {seeds} seeds; runs that never reach 95% plot their budget")
    fig.tight_layout()
    Path(args.figure).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.figure, dpi=130)
    print(f"\nwrote {args.csv} and {args.figure}")


if __name__ == "__main__":
    main()
