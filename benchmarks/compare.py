"""Compare every agent on MountainCar-v0, CartPole-v1 and RobotMaze-v0, plus the
Sutton & Barto Mountain Car check for tile coding.

For each task and agent, 10 seeds (by default): the learning curve (return per
episode), the final performance (mean return over the last 10% of training
episodes, and a greedy evaluation of 20 episodes), the cells or features in
use, environment steps and wall time. Writes a CSV of the runs, one figure per
task and a Markdown table, and prints the table.

    python benchmarks/compare.py --seeds 10 --out docs            # the figures in docs/RESULTS.md
    python benchmarks/compare.py --seeds 2 --scale 0.1 --out /tmp/c  # a quick look

``tabular`` is not run: on continuous observations every observation is a new
row, so it cannot generalize at all (it stops at ``max_states``).
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed

CARTPOLE_BOUNDS = [[-2.4, 2.4], [-3.0, 3.0], [-0.21, 0.21], [-3.5, 3.5]]

#: task -> (env kwargs, training episodes, per-agent parameter overrides)
TASKS = {
    "MountainCar-v0": ({}, 500, {}),
    "CartPole-v1": ({}, 500, {a: {"obs_bounds": CARTPOLE_BOUNDS} for a in ("avq", "grid", "tiles")}),
    "avq/RobotMaze-v0": ({"layout": "lau2002", "move": 0.25}, 300, {}),
}
AGENTS = ("avq", "avq-paper", "grid", "tiles")


def run_one(task: str, agent: str, seed: int, episodes: int) -> dict:
    import avq
    from avq.evaluation import evaluate_policy
    from avq.runs import make_env

    env_kwargs, _, overrides = TASKS[task]
    env = make_env(task, env_kwargs)
    model = avq.make_agent(agent, env, seed=seed, **overrides.get(agent, {}))
    t0 = time.perf_counter()
    model.learn(total_episodes=episodes)
    wall = time.perf_counter() - t0
    hist = model.episode_history()
    returns = np.asarray(hist["return"], float)
    tail = returns[-max(1, episodes // 10):]
    ev = evaluate_policy(model, make_env(task, env_kwargs), n_episodes=20, seed=10_000 + seed)
    return {
        "task": task, "agent": agent, "seed": seed, "episodes": episodes,
        "final_return": float(tail.mean()), "greedy_return": ev["mean_return"],
        "greedy_success": ev["success_rate"], "cells": int(model.n_cells),
        "env_steps": int(model.num_timesteps), "wall_s": round(wall, 2),
        "curve": returns.tolist(),
    }


def mountain_car_check(seed: int, episodes: int = 50) -> float:
    """Tile-coding Sarsa(λ), 8 tilings, uncapped episodes: mean steps over the first 50 episodes."""
    import avq
    from avq.runs import make_env

    env = make_env("MountainCar-v0", {"max_episode_steps": 5000})
    model = avq.make_agent("tiles", env, seed=seed, n_tilings=8).learn(total_episodes=episodes)
    return float(np.mean(model.episode_history()["steps"]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every task's episode budget")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs")
    ap.add_argument("--tasks", default=",".join(TASKS))
    ap.add_argument("--agents", default=",".join(AGENTS))
    args = ap.parse_args()
    out = Path(args.out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "data").mkdir(parents=True, exist_ok=True)
    tasks = [t for t in args.tasks.split(",") if t]
    agents = [a for a in args.agents.split(",") if a]
    jobs = [(t, a, s, max(2, int(TASKS[t][1] * args.scale))) for t in tasks for a in agents for s in range(args.seeds)]
    t0 = time.perf_counter()
    rows = Parallel(n_jobs=args.jobs, verbose=0)(delayed(run_one)(*j) for j in jobs)
    mc = Parallel(n_jobs=args.jobs)(delayed(mountain_car_check)(s) for s in range(args.seeds))
    total = time.perf_counter() - t0

    with open(out / "data" / "compare.csv", "w", newline="") as f:
        cols = [k for k in rows[0] if k != "curve"]
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in cols})
    (out / "data" / "compare_curves.json").write_text(
        json.dumps([{k: r[k] for k in ("task", "agent", "seed", "curve")} for r in rows]))

    from avq.plotting import plot_learning_curves

    lines = ["| task | agent | final return (last 10%) | greedy return | greedy success | cells / features | env steps | s / run |",
             "|---|---|---|---|---|---|---|---|"]
    for t in tasks:
        curves = {a: [np.array(r["curve"]) for r in rows if r["task"] == t and r["agent"] == a] for a in agents}
        plot_learning_curves(curves, out / "figures" / f"compare_{t.replace('/', '-')}.png", ylabel="return",
                             window=20, title=f"{t}: return per episode (mean, 95% interval, {args.seeds} seeds)")
        for a in agents:
            rs = [r for r in rows if r["task"] == t and r["agent"] == a]
            fin = np.array([r["final_return"] for r in rs])
            gr = np.array([r["greedy_return"] for r in rs])
            succ = [r["greedy_success"] for r in rs]
            succ_txt = "-" if any(s is None for s in succ) else f"{np.mean(succ):.0%}"
            cells = np.array([r["cells"] for r in rs])
            lines.append(
                f"| {t} | {a} | {fin.mean():.1f} ± {fin.std():.1f} | {gr.mean():.1f} ± {gr.std():.1f} | {succ_txt} | "
                f"{int(np.median(cells))} [{cells.min()}–{cells.max()}] | {np.mean([r['env_steps'] for r in rs]):.0f} | "
                f"{np.mean([r['wall_s'] for r in rs]):.1f} |")
    lines.append("")
    lines.append(f"Mountain Car check (tiles, 8 tilings, uncapped, first 50 episodes): mean steps per episode "
                 f"{np.mean(mc):.0f} (seeds: {', '.join(f'{v:.0f}' for v in mc)}); Sutton & Barto report about 180-300.")
    lines.append(f"Total wall time {total:.0f} s with {args.jobs} processes.")
    table = "\n".join(lines)
    (out / "data" / "compare_table.md").write_text(table + "\n")
    print(table)


if __name__ == "__main__":
    main()
