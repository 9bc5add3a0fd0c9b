"""Compare every agent on the classic-control tasks and RobotMaze-v0, against a random policy.

Tasks: MountainCar-v0, CartPole-v1, CartPole-v0 and Acrobot-v1 (the classic-control tasks
of Gymnasium with ``Discrete`` actions; CartPole-v0 is CartPole-v1 with a 200-step
limit and a threshold of 195), Pendulum-v1 with five torques (Gymnasium's ``DiscretizeAction``; no success
rule: its greedy success is "-"), and avq/RobotMaze-v0. Agents: ``avq``, ``avq-sarsa``, ``avq-paper``, ``grid``,
``tiles``, ``grid-ps``, ``avq-plan``, and a ``random`` row (uniformly random actions; not an
agent, it learns nothing). On the classic tasks ``avq`` is ``avq-plan`` with the same defaults,
so ``avq-plan`` runs only on RobotMaze (``SAME_AS``). ``tabular`` and ``tabular-ps`` are not run: they keep one
state per distinct observation, and continuous observations never repeat, so they
cannot generalize at all.

For each task, agent and seed (seeds --first-seed .. --first-seed + --seeds - 1):

- ``final_return``: the mean return over the last 10% of the training episodes;
- ``greedy_return``, ``greedy_success``: 20 evaluation episodes with exploration off.
  Success per task (``avq.evaluation.SUCCESS_RULES``): MountainCar reaches the flag,
  CartPole balances for the whole episode (500 steps; 200 on v0), Acrobot swings the tip above the line
  within 500 steps, RobotMaze reaches the goal;
- ``cells``: cells (AVQ agents), bins visited (``grid``, ``grid-ps``) or tiles in use
  (``tiles``) at the end, and ``cells_10`` .. ``cells_100`` after 10%, 25%, 50% and
  100% of the training episodes;
- ``steps_to_threshold``: the environment steps until the mean return of the last
  20 episodes first reaches the task's threshold (``THRESHOLDS``); empty if it never
  does (the table then says "> the run's steps" and counts the runs that got there);
- ``env_steps`` and ``wall_s`` (training only).

The table also gives each agent's mean return over episodes 281-300 against the random
policy's (is it clearly better than random within 300 episodes?).

Writes ``data/compare.csv`` (a row per run), ``data/compare_curves.json`` (returns
per episode), ``data/compare_table.md`` (median [min-max] over seeds; cells over time)
and ``figures/compare_<task>.png`` (learning curves, 95% t-intervals), and prints the
table.

    python benchmarks/compare.py --seeds 10 --first-seed 10 --jobs 2 --out docs   # docs/results/classic-control.md
    python benchmarks/compare.py --seeds 2 --scale 0.1 --out /tmp/c  # a quick look
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed

sys.path.insert(0, str(Path(__file__).parent))  # (benchmarks/dimensions.py, imported where used)

#: CartPole's velocities are unbounded; the agents that cut a box need one (``avq`` does not).
CARTPOLE_BOUNDS = [[-2.4, 2.4], [-3.0, 3.0], [-0.21, 0.21], [-3.5, 3.5]]

#: task -> (env kwargs, training episodes, per-agent parameter overrides)
_CARTPOLE = ({}, 500, {a: {"obs_bounds": CARTPOLE_BOUNDS} for a in ("grid", "tiles", "grid-ps")})  # (v1 and v0)
TASKS = {
    "MountainCar-v0": ({}, 500, {}),
    "CartPole-v1": _CARTPOLE,
    "CartPole-v0": _CARTPOLE,
    # (Acrobot's six dimensions: with tiles' defaults, 8 x 8 per dimension hashed into 4096 weights, the tiles collide
    # and it ended near -400 in 300 episodes, seeds 0-1; with 4 per dimension in a table of 65,536, about 6,700 tiles in
    # use and no collisions, -153 and -126. The baseline gets the better setting.)
    "Acrobot-v1": ({}, 500, {"tiles": {"tiles_per_dim": 4, "iht_size": 65_536}}),
    # (Pendulum never terminates: tiles and grid get the discount and the optimism measured for the tiles learner
    # on it, uniform-actions' gamma 0.99 and q_init 30; with their gamma 1 tiles ended near -860 in 300 episodes.)
    "Pendulum-v1": ({}, 500, {a: {"gamma": 0.99, "q_init": 30.0} for a in ("tiles", "grid")}),
    "avq/RobotMaze-v0": ({"layout": "lau2002", "move": 0.25}, 300, {}),
}
#: task -> the return that the mean of the last 20 training episodes must reach: the usual "solved"
#: levels of the classic tasks (Gym's reward_threshold for MountainCar and Acrobot; 195 is CartPole-v0's)
#: and, on RobotMaze, reaching the goal with at most about 100 moves' worth of penalties.
THRESHOLDS = {
    "MountainCar-v0": -150.0,
    "CartPole-v1": 195.0,
    "CartPole-v0": 195.0,
    "Acrobot-v1": -100.0,
    "Pendulum-v1": -200.0,
    "avq/RobotMaze-v0": -100.0,
}
#: task -> torques: Pendulum's Box action space made Discrete by Gymnasium's DiscretizeAction wrapper (that many
#: evenly spaced torques from -2 to 2), so that the agents for Discrete actions can run it.
ACTION_BINS = {"Pendulum-v1": 5}
AGENTS = ("avq", "avq-sarsa", "avq-paper", "grid", "tiles", "grid-ps", "avq-plan")
#: task -> {agent: the agent it is the same as there (same class and defaults): not run twice}.
SAME_AS = {t: {"avq-plan": "avq"} for t in THRESHOLDS if t != "avq/RobotMaze-v0"}
RANDOM = "random"
WINDOW = 20  # episodes of the running mean that must reach the threshold
EVAL_EPISODES = 20
FRACTIONS = (0.10, 0.25, 0.50, 1.00)  # of training, where cells are counted
EARLY = 300  # episodes: is an agent clearly better than the random policy by then?


class RandomPolicy:
    """Uniformly random actions from a seeded generator (``predict`` as an agent's)."""

    def __init__(self, action_space, seed: int):
        self.n = int(action_space.n)
        self.rng = np.random.default_rng(seed)

    def predict(self, obs, deterministic: bool = True):
        return int(self.rng.integers(self.n)), None


def steps_to_threshold(returns: np.ndarray, steps: np.ndarray, threshold: float) -> int | None:
    """Env steps up to the end of the first episode where the mean of the last WINDOW returns reaches ``threshold``
    (``benchmarks/dimensions.py``'s rule)."""
    from dimensions import to_threshold

    return to_threshold(returns, steps, threshold, WINDOW)[1]


def summarize(task: str, agent: str, seed: int, episodes: int, returns, steps, cells, wall: float, ev: dict) -> dict:
    """One row of the CSV: the run's figures (``cells`` per episode, or None for the random policy)."""
    returns, steps = np.asarray(returns, float), np.asarray(steps, np.int64)
    tail = returns[-max(1, episodes // 10) :]
    row = {
        "task": task,
        "agent": agent,
        "seed": seed,
        "episodes": episodes,
        "final_return": round(float(tail.mean()), 2),
        "greedy_return": round(ev["mean_return"], 2),
        "greedy_success": ev["success_rate"],
        "cells": None if cells is None else int(cells[-1]),
    }
    for f in FRACTIONS:
        row[f"cells_{round(f * 100)}"] = None if cells is None else int(cells[max(1, int(round(f * episodes))) - 1])
    row.update(
        {
            "threshold": THRESHOLDS[task],
            "steps_to_threshold": steps_to_threshold(returns, steps, THRESHOLDS[task]),
            "env_steps": int(steps.sum()),
            "wall_s": round(wall, 2),
            "curve": returns.tolist(),
        }
    )
    return row


def run_one(task: str, agent: str, seed: int, episodes: int, params: dict | None = None) -> dict:
    """One run: ``agent`` on ``task`` with the task's settings for it, and ``params`` (``--set``) on top."""
    import avq
    from avq.evaluation import evaluate_policy
    from avq.runs import make_env

    env_kwargs, _, overrides = TASKS[task]
    env, eval_env = make_env(task, env_kwargs), make_env(task, env_kwargs)
    if task in ACTION_BINS:
        from gymnasium.wrappers import DiscretizeAction

        env, eval_env = (DiscretizeAction(e, bins=ACTION_BINS[task]) for e in (env, eval_env))
    t0 = time.perf_counter()
    if agent == RANDOM:
        policy = RandomPolicy(env.action_space, seed)
        run = evaluate_policy(policy, env, n_eval_episodes=episodes, seed=seed)
        wall = time.perf_counter() - t0
        ev = evaluate_policy(policy, eval_env, n_eval_episodes=EVAL_EPISODES, seed=10_000 + seed)
        return summarize(task, agent, seed, episodes, run["returns"], run["steps"], None, wall, ev)
    model = avq.make_agent(agent, env, seed=seed, **{**overrides.get(agent, {}), **(params or {})})
    model.learn(total_episodes=episodes)
    wall = time.perf_counter() - t0
    hist = model.episode_history()
    ev = evaluate_policy(model, eval_env, n_eval_episodes=EVAL_EPISODES, seed=10_000 + seed)
    return summarize(task, agent, seed, episodes, hist["return"], hist["steps"], hist["n_cells"], wall, ev)


def mountain_car_check(seed: int, episodes: int = 50) -> float:
    """Tile-coding Sarsa(λ), 8 tilings, uncapped episodes: mean steps over the first 50 episodes."""
    import avq
    from avq.runs import make_env

    env = make_env("MountainCar-v0", {"max_episode_steps": 5000})
    model = avq.make_agent("tiles", env, seed=seed, n_tilings=8).learn(total_episodes=episodes)
    return float(np.mean(model.episode_history()["steps"]))


def spread(values, fmt: str = "{:.1f}") -> str:
    """``median [min–max]`` of the seeds' values."""
    v = np.asarray(values, float)
    return f"{fmt.format(np.median(v))} [{fmt.format(v.min())}–{fmt.format(v.max())}]"


def kilo(n: float) -> str:
    return f"{n / 1000:.0f}k" if n >= 10_000 else f"{n / 1000:.1f}k"


def threshold_cell(rs: list[dict]) -> str:
    """Steps to the threshold: the median over seeds, the range over the runs that got there, and how many did.

    A run that never got there counts as more than its own steps, so a median that falls among those
    is given as more than the median of the steps known ("> n")."""
    never = np.array([r["steps_to_threshold"] is None for r in rs])
    known = np.array([r["env_steps"] if n else r["steps_to_threshold"] for r, n in zip(rs, never)], float)
    median = np.median(np.where(never, np.inf, known))
    txt = kilo(median) if np.isfinite(median) else f"> {kilo(np.median(known))}"
    if not never.all():
        txt += f" [{kilo(known[~never].min())}–{kilo(known[~never].max())}]"
    return f"{txt}, {int((~never).sum())}/{len(rs)}"


def run_on(rows: list[dict], task: str, agents: list[str]) -> list[str]:
    """The agents that have rows on the task (not those of ``SAME_AS``, where they are another), in the order of
    ``agents``."""
    return [a for a in agents if any(r["task"] == task and r["agent"] == a for r in rows)]


def tables(rows: list[dict], tasks: list[str], agents: list[str]) -> list[str]:
    """The Markdown tables of the rows: each task with the agents run there (:func:`run_on`)."""
    run = lambda t: run_on(rows, t, agents)  # noqa: E731
    lines = [
        "| task | agent | final return (last 10%) | greedy return | greedy success | cells / features | "
        "env steps to threshold, runs there | env steps | s / run |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for t in tasks:
        for a in run(t):
            rs = [r for r in rows if r["task"] == t and r["agent"] == a]
            succ = [r["greedy_success"] for r in rs]
            succ_txt = "-" if any(s is None for s in succ) else spread(np.multiply(succ, 100), "{:.0f}%")
            cells = "-" if rs[0]["cells"] is None else spread([r["cells"] for r in rs], "{:.0f}")
            lines.append(
                f"| {t} | {a} | {spread([r['final_return'] for r in rs])} | {spread([r['greedy_return'] for r in rs])} | "
                f"{succ_txt} | {cells} | {threshold_cell(rs)} | {np.median([r['env_steps'] for r in rs]):.0f} | "
                f"{np.median([r['wall_s'] for r in rs]):.1f} |"
            )
    lines += [
        "",
        "Cells over time (median [min–max] over seeds) after a fraction of the training episodes:",
        "",
        "| task | agent | " + " | ".join(f"{f:.0%}" for f in FRACTIONS) + " |",
        "|---|---|" + "---|" * len(FRACTIONS),
    ]
    for t in tasks:
        for a in run(t):
            rs = [r for r in rows if r["task"] == t and r["agent"] == a]
            if rs[0]["cells"] is not None:
                cols = [spread([r[f"cells_{round(f * 100)}"] for r in rs], "{:.0f}") for f in FRACTIONS]
                lines.append(f"| {t} | {a} | " + " | ".join(cols) + " |")
    lines += [
        "",
        f"Mean return of episodes {EARLY - WINDOW + 1}–{EARLY} (or the last {WINDOW} before), median "
        "[min–max] over seeds; the seeds above the random policy's best seed:",
        "",
        "| task | agent | return | seeds above random |",
        "|---|---|---|---|",
    ]
    for t in tasks:
        early = {
            a: [float(np.mean(r["curve"][:EARLY][-WINDOW:])) for r in rows if r["task"] == t and r["agent"] == a]
            for a in run(t)
        }
        best_random = max(early[RANDOM])
        for a in run(t):
            above = "-" if a == RANDOM else f"{sum(v > best_random for v in early[a])}/{len(early[a])}"
            lines.append(f"| {t} | {a} | {spread(early[a])} | {above} |")
    return lines


def previous_rows(out: Path) -> list[dict]:
    """The rows of an earlier run in ``out`` (``data/compare.csv`` with the curves of ``data/compare_curves.json``),
    their numbers as :func:`summarize` gives them."""
    curves = {
        (c["task"], c["agent"], int(c["seed"])): c["curve"]
        for c in json.loads((out / "data" / "compare_curves.json").read_text())
    }
    rows = []
    with open(out / "data" / "compare.csv", newline="") as f:
        for r in csv.DictReader(f):
            # (the CSV holds what the writer printed of ints, floats and None: JSON reads each back as it was)
            row = {k: None if v == "" else v if k in ("task", "agent") else json.loads(v) for k, v in r.items()}
            row["curve"] = curves[(row["task"], row["agent"], row["seed"])]
            rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="how many seeds: FIRST_SEED .. FIRST_SEED + SEEDS - 1")
    ap.add_argument("--first-seed", type=int, default=0, help="the first seed (default 0)")
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every task's episode budget")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs")
    ap.add_argument("--tasks", default=",".join(TASKS))
    ap.add_argument(
        "--agents",
        default=",".join(AGENTS),
        help=f"agent names, and {RANDOM!r} (added if left out; with --update, on the tasks that have no rows of it)",
    )
    ap.add_argument(
        "--update",
        action="store_true",
        help="keep the rows of OUT/data/compare.csv for the tasks and agents not run now, and write the "
        "tables and figures of them all (the same seeds)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="for trials: a parameter given to every agent run on top of the task's settings, read as "
        "`avq train --set` reads it, e.g. --set 'scale_factor=[3,3,3,3,1,1]' (repeatable; not with "
        "--out docs)",
    )
    args = ap.parse_args()
    from avq.cli import UsageError, key_values

    try:
        params = key_values(args.set, "--set")  # (read as `avq train --set` reads them)
    except UsageError as e:
        ap.error(str(e))
    out = Path(args.out)
    if params and out.resolve() == (Path(__file__).resolve().parents[1] / "docs"):
        ap.error(f"--set gives trial settings; write them elsewhere than the results in {out} (e.g. --out /tmp/trial)")
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "data").mkdir(parents=True, exist_ok=True)
    tasks = [t for t in args.tasks.split(",") if t]
    agents = [a for a in args.agents.split(",") if a]
    previous = previous_rows(out) if args.update else []
    # The random policy runs on every task, unless asked for or (--update) its rows for the task are kept.
    has_random = {r["task"] for r in previous if r["agent"] == RANDOM}
    jobs = [
        (t, a, s, max(WINDOW, int(TASKS[t][1] * args.scale)), params)
        for t in tasks
        for a in agents + ([RANDOM] if RANDOM not in agents and t not in has_random else [])
        if a not in SAME_AS.get(t, {})
        for s in range(args.first_seed, args.first_seed + args.seeds)
    ]
    t0 = time.perf_counter()
    rows = Parallel(n_jobs=args.jobs, verbose=5)(delayed(run_one)(*j) for j in jobs)
    if args.update:
        kept = [r for r in previous if (r["task"], r["agent"]) not in {(t, a) for t, a, *_ in jobs}]
        rows = kept + rows
        tasks = list(dict.fromkeys([t for t in TASKS if any(r["task"] == t for r in rows)]))
        agents = list(dict.fromkeys([a for a in (*AGENTS, RANDOM) if any(r["agent"] == a for r in rows)]))
    else:
        agents = list(dict.fromkeys([*agents, *(a for _, a, *_ in jobs)]))
    mc = (
        Parallel(n_jobs=args.jobs)(
            delayed(mountain_car_check)(s) for s in range(args.first_seed, args.first_seed + args.seeds)
        )
        if "MountainCar-v0" in tasks
        else []
    )
    total = time.perf_counter() - t0

    with open(out / "data" / "compare.csv", "w", newline="") as f:
        cols = [k for k in rows[0] if k != "curve"]
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in cols})
    (out / "data" / "compare_curves.json").write_text(
        json.dumps([{k: r[k] for k in ("task", "agent", "seed", "curve")} for r in rows])
    )

    from avq.plotting import plot_learning_curves

    for t in tasks:
        curves = {
            a: [np.array(r["curve"]) for r in rows if r["task"] == t and r["agent"] == a]
            for a in run_on(rows, t, agents)
        }
        plot_learning_curves(
            curves,
            out / "figures" / f"compare_{t.replace('/', '-')}.png",
            ylabel="return",
            xlabel="episode",
            window=WINDOW,
            title=f"{t}: return per episode, {args.seeds} seeds (threshold {THRESHOLDS[t]:g})",
            higher_is_better=True,
        )
    lines = tables(rows, tasks, agents)
    lines.append("")
    lines.append(
        "Thresholds (mean return of the last 20 episodes): " + ", ".join(f"{t} {THRESHOLDS[t]:g}" for t in tasks) + "."
    )
    if mc:
        lines.append(
            f"Mountain Car check (tiles, 8 tilings, uncapped, first 50 episodes): mean steps per episode "
            f"{np.mean(mc):.0f} (seeds: {', '.join(f'{v:.0f}' for v in mc)}); Sutton & Barto report about 180-300."
        )
    lines.append(f"Total wall time {total:.0f} s with {args.jobs} processes.")
    table = "\n".join(lines)
    (out / "data" / "compare_table.md").write_text(table + "\n")
    print(table)


if __name__ == "__main__":
    main()
