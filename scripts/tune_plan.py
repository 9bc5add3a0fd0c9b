"""How avq-plan's defaults were explored: variants on the tuning mazes, against tabular-ps.

The tuning mazes are lau2002 refined k = 1, 2, 4 and random_layout(side, side, 0.2, seed=1000 + side) for
sides 22 and 42; seeds 0-9. Every run learns in chunks of episodes (1, 2, 4, ... 50) until the greedy
policy succeeds from 95% of the starts, budget 300,000 env steps. One row per run is appended to
docs/data/tuning_plan.csv (that file was measured at commit 352376a, with the defaults of then:
split_threshold 5, tol 1e-6; docs/results/planning.md).

    python scripts/tune_plan.py default,st10,tabular all 0,1,2,3,4,5,6,7,8,9
"""

import csv
import json
import os
import sys
import time

import numpy as np

BUDGET = 300_000
OUT = "docs/data/tuning_plan.csv"
FIELDS = [
    "variant",
    "agent",
    "overrides",
    "maze",
    "squares",
    "seed",
    "reached",
    "steps",
    "success",
    "cells",
    "backups",
    "queued",
    "episodes",
    "goal_eps",
    "splits_dup",
    "empty_cells",
    "wall_s",
    "error",
]


def mazes():
    import avq

    return {
        "lau2002_k1": avq.envs.refine_layout("lau2002", 1),
        "lau2002_k2": avq.envs.refine_layout("lau2002", 2),
        "lau2002_k4": avq.envs.refine_layout("lau2002", 4),
        "rand22": avq.envs.random_layout(22, 22, 0.2, seed=1022),
        "rand42": avq.envs.random_layout(42, 42, 0.2, seed=1042),
    }


def learn_until(agent, eval_env, budget, limit):
    import avq

    chunk = 1
    while agent.num_timesteps < budget:
        agent.learn(total_episodes=chunk)
        s = avq.evaluate_maze(agent, eval_env, max_steps=limit)["success_rate"]
        if s >= 0.95:
            return True, s
        chunk = min(2 * chunk, 50)
    return False, s


def run(variant, agent_name, overrides, maze, seed):
    import gymnasium as gym

    import avq

    rows = mazes()[maze]
    limit = 4 * (len(rows) + len(rows[0]))
    squares = sum(r.count(".") + r.count("G") + r.count("S") for r in rows)
    rec = dict(
        variant=variant,
        agent=agent_name,
        overrides=json.dumps(overrides),
        maze=maze,
        squares=squares,
        seed=seed,
        error="",
    )
    t0 = time.time()
    try:
        env = gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=limit)
        eval_env = gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=limit)
        agent = avq.make_agent(agent_name, env, seed=seed, **overrides)
        ok, s = learn_until(agent, eval_env, BUDGET, limit)
        rec.update(
            reached=int(ok),
            steps=int(agent.num_timesteps),
            success=round(float(s), 4),
            cells=int(getattr(agent, "n_cells", -1)),
            backups=int(getattr(agent, "backups_", -1)),
            queued=int(getattr(agent, "queued_", -1)),
            episodes=int(agent.num_episodes),
        )
        h = agent.history_.columns()
        rec["goal_eps"] = int((np.asarray(h["steps"]) < limit).sum())  # training episodes that reached the goal
        if agent_name == "avq-plan":
            cb = agent.codebook_
            _, inv = np.unique(cb, axis=0, return_inverse=True)
            rec["splits_dup"] = int(len(cb) - len(np.unique(inv)))  # vectors identical to another vector
            free = np.array([[x, y] for y, r in enumerate(rows) for x, ch in enumerate(r) if ch != "#"], float)
            owned = np.bincount(agent.cells(free), minlength=len(cb))
            rec["empty_cells"] = int((owned == 0).sum())  # cells that own no free square
    except Exception as e:  # record, keep going
        import traceback

        rec.update(
            reached=0, steps=BUDGET, error=repr(e)[:300] + " | " + traceback.format_exc()[-300:].replace("\n", " ")
        )
    rec["wall_s"] = round(time.time() - t0, 1)
    return rec


def save(recs):
    new = not os.path.exists(OUT)
    with open(OUT, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        if new:
            w.writeheader()
        for r in recs:
            w.writerow({k: r.get(k, "") for k in FIELDS})


def main(jobs):
    from joblib import Parallel, delayed

    par = Parallel(n_jobs=2, return_as="generator_unordered")
    for rec in par(delayed(run)(*j) for j in jobs):
        save([rec])
        print(rec, flush=True)


ALL_MAZES = ["lau2002_k1", "lau2002_k2", "lau2002_k4", "rand22", "rand42"]
VARIANTS = {
    "default": {},
    "cg_off": {"collision_growth": False},
    "st2": {"split_threshold": 2.0},
    "st7": {"split_threshold": 7.0},
    "st10": {"split_threshold": 10.0},
    "st20": {"split_threshold": 20.0},
    "g099": {"gamma": 0.99},
    "g095": {"gamma": 0.95},
    "nb10": {"n_backups": 10},
    "nb1000": {"n_backups": 1000},
    "os_off": {"outcome_split": False},
    "ka2": {"known_after": 2},
    # combinations (step 6)
    "st10_ka2": {"split_threshold": 10.0, "known_after": 2},
    "st20_ka2": {"split_threshold": 20.0, "known_after": 2},
    "st10_nb1000": {"split_threshold": 10.0, "n_backups": 1000},
    "st20_nb1000": {"split_threshold": 20.0, "n_backups": 1000},
}

if __name__ == "__main__":
    names = sys.argv[1].split(",")
    mz = sys.argv[2].split(",") if len(sys.argv) > 2 and sys.argv[2] != "all" else ALL_MAZES
    seeds = [int(s) for s in sys.argv[3].split(",")] if len(sys.argv) > 3 else [0, 1, 2]
    jobs = []
    for m in mz:
        for s in seeds:
            for n in names:
                if n == "tabular":
                    jobs.append(("tabular", "tabular-ps", {}, m, s))
                else:
                    jobs.append((n, "avq-plan", VARIANTS[n], m, s))
    main(jobs)
