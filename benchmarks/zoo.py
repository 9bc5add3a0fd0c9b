"""Classic control at RL Baselines3 Zoo's budgets: the general ``avq`` against the zoo's DQN, run here, on the same
env steps.

Tasks: MountainCar-v0, CartPole-v1, Acrobot-v1 and LunarLander-v3 (``pip install "gymnasium[box2d]"``), each with
the zoo's DQN budget in env steps (``ZOO_DQN``'s ``n_timesteps``: 120 k, 50 k, 100 k, 100 k) for every agent:

* ``avq``: the general entry (``PlanningAVQ``'s signature defaults: what a task of the user's own gets);
* ``avq-entry``: ``make_agent("avq")``, the per-task entry, on the tasks that have one (CartPole-v1, Acrobot-v1);
* ``tiles``: tile-coding Sarsa(λ) with ``benchmarks/compare.py``'s settings for the task (on Acrobot 4 tiles a
  dimension in a table of 65,536, its better setting; on CartPole a box for the velocities);
* ``dqn``: Stable-Baselines3's DQN with the zoo's hyper-parameters (:data:`dimensions.ZOO_DQN`; ``pip install
  stable-baselines3 torch``, not an extra of avq), its ε schedule the zoo's in env steps;
* ``random``: uniformly random actions.

With ``--noise K`` every task has ``K`` noise dimensions appended (:class:`avq.envs.IrrelevantDims`, a uniform draw
in [0, 1] each step): tiles' per-dimension settings are extended over them, and ``avq-entry`` is not run (a wrapped
task gets the general defaults). The rows record ``noise``; the figure of ``--noise K`` is ``zoo_noiseK.png``.

Every agent learns in 20 chunks of a twentieth of the budget; after each its greedy policy plays 10 episodes
(seeded ``10,000 + seed``, the same starts at every check), as the zoo's evaluation does. Per run:

* ``steps_to_threshold``: the env steps at the first check whose greedy mean reaches Gymnasium's reward threshold
  (MountainCar -110, CartPole 475, Acrobot -100, LunarLander 200); empty if none does;
* ``greedy_return``: the last check's mean, ``best_greedy`` the best check's; ``final_return``: the mean of the last
  100 training episodes (with the agent's exploration); ``cells`` (the Q-network's weights for ``dqn``, tiles in
  use for ``tiles``), ``wall_s`` (learning and checks), ``steps_per_s`` (learning only).

Writes ``OUT/zoo.csv`` (``--out``, default ``docs/data``; rows of (task, agent, seed) not run are kept, so agents
and seeds can be added one at a time) and prints a Markdown table. Seeds 10-19 are held out from all tuning.
``--set KEY=VALUE`` changes a parameter of ``avq`` and ``avq-entry``: a variant, written elsewhere than
``docs/data`` and drawn in no figure. ``--times K`` multiplies every budget by ``K`` (written elsewhere than
``docs/data``: the rows there are at the zoo's budgets).

    python benchmarks/zoo.py --seeds 10-19                      # every agent: about 100 min on 2 cores
    python benchmarks/zoo.py --seeds 10-19 --agents avq,tiles   # without DQN: 5 min
    python benchmarks/zoo.py --quick --out /tmp/zoo             # a check: budgets / 20, seed 0
    python benchmarks/zoo.py --seeds 10-19 --tasks MountainCar-v0,CartPole-v1 --noise 4   # 4 noise dimensions
    python benchmarks/zoo.py --agents avq --set compose_crossings=true --out /tmp/zoo_cc  # a variant of avq's
    python benchmarks/zoo.py --tasks LunarLander-v3 --agents avq,tiles --times 10 --out /tmp/zoo_x10  # 1 M env steps
"""

from __future__ import annotations

import argparse
import sys
import textwrap
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import yaml
from joblib import delayed

sys.path.insert(0, str(Path(__file__).parent))
from compare import (
    TASKS as COMPARE_TASKS,  # noqa: E402
    RandomPolicy,  # noqa: E402
)
from dimensions import (  # noqa: E402
    ZOO_DQN,
    ZooDQN,
    censored_median,
    extend_dims,
    finished,
    read_csv,
    require_sb3,
    seeds_of,
    spread,
    write_csv,
)

import avq  # noqa: E402
from avq.agents.registry import defaults_key  # noqa: E402
from avq.envs import IrrelevantDims  # noqa: E402
from avq.evaluation import evaluate_policy  # noqa: E402

TASKS = ("MountainCar-v0", "CartPole-v1", "Acrobot-v1", "LunarLander-v3")
AGENTS = ("avq", "avq-entry", "tiles", "dqn", "random")
CHECKS, CHECK_EPISODES, TAIL = 20, 10, 100
#: The project's results, which a check (``--quick``) or a variant (``--set``) must not overwrite.
DOCS_DATA = Path(__file__).resolve().parents[1] / "docs" / "data"
FIELDS = (
    "task", "noise", "agent", "seed", "budget", "env_steps", "episodes", "threshold", "steps_to_threshold", "greedy_return",
    "best_greedy", "final_return", "cells", "wall_s", "steps_per_s",
)  # fmt: skip


def has_entry(task: str) -> bool:
    """Whether ``avq`` has an entry of its own on ``task`` (else ``avq-entry`` is ``avq`` and not run)."""
    return defaults_key("avq", task) != "*"


def first_reaching(steps: list[int], means: list[float], threshold: float) -> int | None:
    """The env steps ``steps[i]`` of the first check ``i`` whose greedy mean ``means[i]`` reaches ``threshold``."""
    return next((s for s, m in zip(steps, means) if m >= threshold), None)


def make_env(task: str, noise: int) -> gym.Env:
    """``task``, with ``noise`` noise dimensions appended when it is above 0."""
    return IrrelevantDims(gym.make(task), noise) if noise else gym.make(task)


def make(name: str, env: gym.Env, task: str, seed: int, budget: int, noise: int = 0, params: dict | None = None):
    """The learner ``name`` on ``env`` (``task`` with ``noise`` dimensions appended): an agent of avq's,
    :class:`ZooDQN` for ``dqn``, or for ``random`` the policy that the checks play (its training is played by
    another, :func:`run`). ``params`` (``--set``) change ``avq``'s and ``avq-entry``'s parameters."""
    if name == "dqn":
        return ZooDQN(env, task, seed, budget)
    if name == "random":
        return RandomPolicy(env.action_space, seed)
    if name == "avq":
        return avq.PlanningAVQ(env, seed=seed, **(params or {}))
    overrides = extend_dims(COMPARE_TASKS[task][2].get(name, {}) if task in COMPARE_TASKS else {}, noise)
    if name == "avq-entry":
        return avq.make_agent("avq", env, seed=seed, **overrides, **(params or {}))
    return avq.make_agent(name, env, seed=seed, **overrides)


def run(name: str, task: str, seed: int, budget: int, noise: int = 0, params: dict | None = None) -> dict:
    """One run: ``name`` learns ``budget`` env steps of ``task`` (with ``noise`` dimensions appended), its greedy
    policy checked after every :data:`CHECKS`-th of them (``dqn`` in one call of SB3's ``learn``, the others in
    chunks); ``params`` as :func:`make`."""
    env, eval_env = make_env(task, noise), make_env(task, noise)
    agent = make(name, env, task, seed, budget, noise, params)
    threshold = float(gym.spec(task).reward_threshold)
    t0, evaluating, greedy, at = time.perf_counter(), 0.0, [], []

    def check(steps_now: int) -> None:
        nonlocal evaluating
        t = time.perf_counter()
        greedy.append(
            evaluate_policy(agent, eval_env, n_eval_episodes=CHECK_EPISODES, seed=10_000 + seed)["mean_return"]
        )
        at.append(int(steps_now))
        evaluating += time.perf_counter() - t

    chunk, random_returns, played = budget // CHECKS, [], 0
    player = RandomPolicy(env.action_space, seed) if name == "random" else None
    if name == "dqn":  # (one call of SB3's learn, checked from a callback)
        agent.learn_checked(chunk, check)
    else:
        for c in range(1, CHECKS + 1):
            target = budget if c == CHECKS else c * chunk
            if player is not None:  # (random learns nothing: its training is what a policy of its own plays)
                while played < target:
                    ep = evaluate_policy(player, env, n_eval_episodes=1, seed=seed * 100_000 + len(random_returns))
                    random_returns.append(ep["returns"][0])
                    played += int(ep["steps"][0])
            else:
                agent.learn(total_timesteps=target - agent.num_timesteps)
            check(played if player is not None else agent.num_timesteps)
    learning = time.perf_counter() - t0 - evaluating
    steps_now = at[-1]
    if name == "random":
        returns, cells = np.array(random_returns), 0
    else:
        returns, cells = np.asarray(agent.episode_history()["return"], float), int(agent.n_cells)
    return dict(
        task=task, noise=noise, agent=name, seed=seed, budget=budget, env_steps=int(steps_now), episodes=len(returns),
        threshold=threshold, steps_to_threshold=first_reaching(at, greedy, threshold), greedy_return=round(greedy[-1], 1),
        best_greedy=round(max(greedy), 1), final_return=round(float(np.mean(returns[-TAIL:])), 1), cells=cells,
        wall_s=round(time.perf_counter() - t0, 1), steps_per_s=round(steps_now / max(learning, 1e-9)),
    )  # fmt: skip


def table(rows: list[dict]) -> None:
    print(
        "| task | noise | agent | env steps to threshold, runs there | greedy return at the end | "
        "training return (last 100) | cells | env steps/s | s/run |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    noises = sorted({r["noise"] for r in rows})
    for task, noise, name in ((t, k, n) for t in TASKS for k in noises for n in AGENTS):
        rs = [r for r in rows if r["task"] == task and r["noise"] == noise and r["agent"] == name]
        if rs:
            ok = [r["steps_to_threshold"] is not None for r in rs]
            st, cens = censored_median([r["steps_to_threshold"] or r["env_steps"] for r in rs], ok)
            print(
                f"| {task} | {noise:.0f} | {name} | {'>' * cens}{st:,.0f}, {sum(ok)}/{len(rs)} | "
                f"{spread([r['greedy_return'] for r in rs], '{:.1f}')} | "
                f"{spread([r['final_return'] for r in rs], '{:.1f}')} | {spread([r['cells'] for r in rs])} | "
                f"{np.median([r['steps_per_s'] for r in rs]):,.0f} | {np.median([r['wall_s'] for r in rs]):.0f} |"
            )


def plot(rows: list[dict], path: Path, noise: int = 0) -> None:
    """Per task, of the rows with ``noise`` noise dimensions: the greedy return at the end and the env steps to the
    threshold, a dot per seed (open triangles at the budget: not reached), the median a bar; the threshold and the
    random policy's median dotted."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in rows if r["noise"] == noise]
    tasks = [t for t in TASKS if any(r["task"] == t for r in rows)]
    fig, axes = plt.subplots(2, len(tasks), figsize=(3.3 * len(tasks), 6.4), squeeze=False)
    for j, task in enumerate(tasks):
        names = [n for n in AGENTS if n != "random" and any(r["task"] == task and r["agent"] == n for r in rows)]
        top, bottom = axes[0][j], axes[1][j]
        rng = np.random.default_rng(0)  # (the dots' horizontal jitter only)
        for i, name in enumerate(names):
            color = f"C{AGENTS.index(name)}"  # (an agent's colour is the same in every panel)
            rs = [r for r in rows if r["task"] == task and r["agent"] == name]
            x = i + rng.uniform(-0.15, 0.15, len(rs))
            g = [r["greedy_return"] for r in rs]
            top.plot(x, g, "o", color=color, ms=4, alpha=0.7)
            top.plot([i - 0.3, i + 0.3], [np.median(g)] * 2, color=color, lw=2)
            hit = [(xi, r["steps_to_threshold"]) for xi, r in zip(x, rs) if r["steps_to_threshold"] is not None]
            miss = [(xi, r["budget"]) for xi, r in zip(x, rs) if r["steps_to_threshold"] is None]
            for pts, marker in ((hit, "o"), (miss, "^")):
                if pts:
                    bottom.plot(*zip(*pts), marker, color=color, ms=5, alpha=0.7, mfc="none" if marker == "^" else None)
        threshold = next(r["threshold"] for r in rows if r["task"] == task)
        top.axhline(threshold, color="k", ls=":", lw=1, label=f"threshold {threshold:g}")
        random = [r["greedy_return"] for r in rows if r["task"] == task and r["agent"] == "random"]
        if random:
            top.axhline(np.median(random), color="grey", ls="--", lw=1, label="random policy")
        budget = next(r["budget"] for r in rows if r["task"] == task)
        bottom.axhline(budget, color="k", ls=":", lw=1, label=f"budget {budget:,}")
        top.set(title=task, ylabel="greedy return at the end\n(10 episodes)" if j == 0 else None)
        bottom.set(yscale="log", ylabel="env steps to the threshold\n(^: not reached)" if j == 0 else None)
        for ax in (top, bottom):
            ax.set_xticks(range(len(names)), names, rotation=30, fontsize=8)
            ax.grid(alpha=0.3, axis="y")
            ax.legend(fontsize=7, loc="best", framealpha=0.6)
    seeds = sorted({r["seed"] for r in rows})
    which = f"seed {seeds[0]}" if len(seeds) == 1 else f"seeds {seeds[0]}-{seeds[-1]}"
    added = f", {noise} noise dimensions appended" if noise else ""
    title = f"RL Zoo's DQN budgets, every agent on the same env steps{added}: {which}"
    fig.suptitle(textwrap.fill(title, width=int(12 * fig.get_figwidth())), fontsize=10)  # (about 12 characters an inch)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    print(f"wrote {path}")


def variant(ap: argparse.ArgumentParser, pairs: list[str], names: list[str], out: Path, task: str) -> dict:
    """``--set``'s parameters, each checked by making ``avq`` with it (``ap.error``, exit 2, on a bad one), or {}."""
    if not pairs:
        return {}
    if not {"avq", "avq-entry"} & set(names):
        ap.error("--set changes avq and avq-entry, and --agents names neither; add one of them")
    if out.resolve() == DOCS_DATA:
        ap.error("--set makes a variant: write it elsewhere than docs/data (e.g. --out /tmp/zoo_variant)")
    params = {}
    for pair in pairs:
        key, eq, value = pair.partition("=")
        if not eq or not key:
            ap.error(f"--set {pair}: give KEY=VALUE, as --set compose_crossings=true")
        params[key] = yaml.safe_load(value)
    try:
        avq.PlanningAVQ(make_env(task, 0), **params)
    except (TypeError, ValueError) as exc:
        ap.error(f"--set {' '.join(pairs)}: avq refuses it ({exc}); see help(avq.PlanningAVQ)")
    return params


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("--tasks", default=",".join(TASKS), help=f"comma-separated, of {', '.join(TASKS)}")
    ap.add_argument("--agents", default=",".join(AGENTS), help=f"comma-separated, of {', '.join(AGENTS)}")
    ap.add_argument("--seeds", default="10-19", help="a range, as 10-19 (the default: held out from tuning)")
    ap.add_argument("--quick", action="store_true", help="budgets / 20, a check")
    ap.add_argument("--times", type=float, default=1.0, help="budgets x TIMES (written elsewhere than docs/data)")
    ap.add_argument("--noise", type=int, default=0, help="noise dimensions appended to every task (default 0)")
    ap.add_argument(
        "--plot", action="store_true", help="only the figure, from OUT/zoo.csv: OUT/../figures/zoo.png (zoo_noiseK.png)"
    )
    ap.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE",
        help="a parameter of avq and avq-entry (a YAML value; repeatable): a variant, written elsewhere than docs/data",
    )  # fmt: skip
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs/data")
    args = ap.parse_args()
    tasks, names = args.tasks.split(","), args.agents.split(",")
    if bad := [t for t in tasks if t not in TASKS]:
        ap.error(f"--tasks {','.join(bad)}: choose from {', '.join(TASKS)}")
    if bad := [n for n in names if n not in AGENTS]:
        ap.error(f"--agents {','.join(bad)}: choose from {', '.join(AGENTS)}")
    params = variant(ap, args.set, names, Path(args.out), tasks[0])
    if args.quick and Path(args.out).resolve() == DOCS_DATA:
        ap.error("--quick is a check: write it elsewhere than docs/data (e.g. --out /tmp/zoo)")
    if not args.times > 0:
        ap.error(f"--times {args.times}: give a multiple of the zoo's budgets above 0, as 10")
    if args.times != 1 and Path(args.out).resolve() == DOCS_DATA:
        ap.error("--times changes the budgets: write it elsewhere than docs/data (e.g. --out /tmp/zoo_x10)")
    if args.noise < 0:
        ap.error(f"--noise {args.noise}: give a count of noise dimensions, 0 or more")
    figure = Path(args.out).resolve().parent / "figures" / f"zoo{f'_noise{args.noise}' if args.noise else ''}.png"
    if args.plot:
        if not (Path(args.out) / "zoo.csv").exists():
            ap.error(f"--plot: no {Path(args.out) / 'zoo.csv'}; run the study first (without --plot)")
        return plot(read_csv(Path(args.out) / "zoo.csv"), figure, args.noise)
    if "dqn" in names:
        require_sb3()
    budgets = {t: int(ZOO_DQN[t]["n_timesteps"] * args.times) // (20 if args.quick else 1) for t in tasks}
    jobs = [
        delayed(run)(n, t, s, budgets[t], args.noise, params)
        for t in tasks
        for n in names
        for s in seeds_of(args.seeds)
        if n != "avq-entry" or (has_entry(t) and not args.noise)
    ]
    print(f"{len(jobs)} runs: {', '.join(f'{t} {budgets[t]:,}' for t in tasks)} env steps, seeds {args.seeds}")
    t0 = time.perf_counter()
    rows = write_csv(Path(args.out) / "zoo.csv", FIELDS, finished(args.jobs, jobs), ("task", "noise", "agent", "seed"))
    table(rows)
    if not params:  # (a variant's rows are a table to read beside the CSV's, not the figure's)
        plot(rows, figure, args.noise)
    print(f"({time.perf_counter() - t0:.0f} s with {args.jobs} jobs)")


if __name__ == "__main__":
    main()
