"""How much optimism the general ``avq`` needs: ``v_opt`` against the final return, on a task with shaped rewards
(LunarLander-v3), on one whose rewards only count survival (CartPole-v1) and on MountainCar-v0 with
potential-based shaping (``MountainCar-shaped``: rewards of both signs, the same best policy; a task never
used to choose the rule, its final return unshaped).

``avq``'s general entry (``PlanningAVQ``'s signature defaults, as ``make_agent`` gives a task of the user's own;
the entries of CartPole-v1 and Acrobot-v1 are not used) with ``v_opt`` "auto" (R-max's bound: the horizon times the largest reward
seen) and with fixed values, beside ``tiles`` and a random policy. Per run: the final return (mean of the last
100 episodes), the cells and ``v_opt_`` at the end; per configuration the median and range over the seeds.
Writes ``OUT/optimism_seedsS.csv`` (``--out``, default ``docs/data``; ``S`` the ``--seeds``), replacing the rows of the
configurations run and keeping the file's others; LunarLander-v3 needs ``pip install "gymnasium[box2d]"``.

    python benchmarks/optimism.py                                  # seeds 0-2: 5 min on 2 cores
    python benchmarks/optimism.py --seeds 10-19 --tasks LunarLander-v3 --v-opt auto 0
    python benchmarks/optimism.py --seeds 0-14 --tasks MountainCar-shaped --v-opt auto --baselines
    python benchmarks/optimism.py --seeds 10-19 --tasks CartPole-v1 MountainCar-v0 Acrobot-v1 --v-opt auto
    python benchmarks/optimism.py --seeds 0-4 --tasks CartPole-v1 MountainCar-v0 Acrobot-v1 --v-opt auto --axis-share 0.8

``--axis-share`` gives ``avq`` that ``axis_share`` (the outcome split across one axis; written to
``OUT/optimism_seedsS_axisX.csv``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
from gymnasium.wrappers import RecordEpisodeStatistics
from joblib import Parallel, delayed

sys.path.insert(0, str(Path(__file__).parent))
from dimensions import CARTPOLE_BOUNDS, seeds_of, write_csv  # noqa: E402

import avq  # noqa: E402
from avq.envs import PotentialShaping  # noqa: E402

#: Episodes per run and the ``v_opt`` values measured on each task.
TASKS = {
    "LunarLander-v3": 1000,
    "CartPole-v1": 300,
    "MountainCar-shaped": 300,
    "MountainCar-v0": 300,
    "Acrobot-v1": 300,
}
#: The tasks of the default run (the others on demand: the general entry on the classic tasks, ``--tasks``).
DEFAULT_TASKS = ("LunarLander-v3", "CartPole-v1", "MountainCar-shaped")
V_OPTS = ("auto", 200.0, 100.0, 30.0, 0.0, -50.0)
TAIL = 100
FIELDS = ("task", "agent", "v_opt", "seed", "episodes", "final_return", "cells", "v_opt_end", "env_steps", "wall_s")
#: With ``--axis-share``, a column more.
AXIS_FIELDS = (*FIELDS, "axis_share")


def shaped_mountain_car(episodes: int) -> tuple[gym.Env, RecordEpisodeStatistics]:
    """MountainCar-v0 with potential-based shaping (:class:`avq.envs.PotentialShaping`): phi 100 times the car's
    height, so rewards take both signs and the best policy is the same; and, inside it, the recorder of each
    episode's return unshaped (what the final return reports)."""
    unshaped = RecordEpisodeStatistics(gym.make("MountainCar-v0"), buffer_length=episodes)
    return PotentialShaping(unshaped, lambda obs: 100.0 * (0.45 * np.sin(3.0 * obs[0]) + 0.55)), unshaped


def run(task: str, agent: str, v_opt: str | float, seed: int, episodes: int, axis_share: float | None = None) -> dict:
    """One run: ``avq`` (the general entry) with ``v_opt`` (and ``axis_share`` where given), ``tiles`` or ``random``."""
    env, unshaped = shaped_mountain_car(episodes) if task == "MountainCar-shaped" else (gym.make(task), None)
    t = time.perf_counter()
    if agent == "random":
        env.action_space.seed(seed)
        returns, steps = [], 0
        for e in range(episodes):
            env.reset(seed=seed * 100_000 + e)
            total, done = 0.0, False
            while not done:
                _, r, term, trunc, _ = env.step(env.action_space.sample())
                total, done, steps = total + float(r), term or trunc, steps + 1
            returns.append(unshaped.return_queue[-1] if unshaped is not None else total)
        cells, v_end = 0, None
    else:
        if agent == "avq":
            model = avq.PlanningAVQ(
                env, v_opt=v_opt, seed=seed, **({} if axis_share is None else {"axis_share": axis_share})
            )
        else:  # (tiles cuts a box: CartPole's velocities are unbounded)
            model = avq.make_agent(
                agent, env, seed=seed, **({"obs_bounds": CARTPOLE_BOUNDS} if "CartPole" in task else {})
            )
        model.learn(total_episodes=episodes)
        returns, steps, cells = model.episode_history()["return"], model.num_timesteps, model.n_cells
        returns = list(unshaped.return_queue) if unshaped is not None else returns
        v_end = round(model.v_opt_, 1) if agent == "avq" else None
    row = dict(
        task=task,
        agent=agent,
        v_opt=v_opt if agent == "avq" else "",
        seed=seed,
        episodes=episodes,
        final_return=round(float(np.mean(returns[-TAIL:])), 1),
        cells=cells,
        v_opt_end=v_end,
        env_steps=steps,
        wall_s=round(time.perf_counter() - t, 1),
    )
    return row if axis_share is None else row | {"axis_share": axis_share if agent == "avq" else ""}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tasks", nargs="+", default=list(DEFAULT_TASKS), choices=list(TASKS))
    ap.add_argument("--seeds", default="0-2")
    ap.add_argument("--v-opt", nargs="+", default=[str(v) for v in V_OPTS], help='"auto" or numbers')
    ap.add_argument("--baselines", nargs="*", default=["tiles", "random"], choices=["tiles", "random"])
    ap.add_argument("--episodes", type=int, default=None, help="per run, instead of each task's own (a check)")
    ap.add_argument("--axis-share", type=float, default=None, help="avq's axis_share (default: none)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs/data")
    args = ap.parse_args()
    v_opts = [v if v == "auto" else float(v) for v in args.v_opt]
    configs = [("avq", v) for v in v_opts] + [(b, "") for b in args.baselines]
    jobs = [
        delayed(run)(task, agent, v, seed, args.episodes or TASKS[task], args.axis_share)
        for task in args.tasks
        for agent, v in configs
        for seed in seeds_of(args.seeds)
    ]
    rows = Parallel(n_jobs=args.jobs)(jobs)
    axis = "" if args.axis_share is None else f"_axis{args.axis_share:g}"
    out = Path(args.out) / f"optimism_seeds{args.seeds}{axis}.csv"
    # (the file's rows of other tasks, agents or v_opt values are kept: a run of some of them adds to it)
    write_csv(out, FIELDS if args.axis_share is None else AXIS_FIELDS, rows, ("task", "agent", "v_opt", "seed"))
    print(f"| task | agent | v_opt | final return (last {TAIL}), median [range] | cells | v_opt at the end |")
    print("|---|---|---|---|---|---|")
    for task in args.tasks:
        for agent, v in configs:
            rs = [
                r
                for r in rows
                if r["task"] == task and r["agent"] == agent and r["v_opt"] == (v if agent == "avq" else "")
            ]
            fin = [r["final_return"] for r in rs]
            v_end = np.median([r["v_opt_end"] for r in rs]) if agent == "avq" else None
            print(
                f"| {task} | {agent} | {v} | {np.median(fin):.1f} [{min(fin):.1f} to {max(fin):.1f}] | "
                f"{np.median([r['cells'] for r in rs]):,.0f} | {'' if v_end is None else f'{v_end:,.0f}'} |"
            )
    print(f"(written {out})")


if __name__ == "__main__":
    main()
