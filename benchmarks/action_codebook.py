"""AVQ on the action space: the adaptive action codebook against fixed uniform action grids.

On Pendulum-v1 and MountainCarContinuous-v0, "avq-actions" (a codebook grown and
merged from 3 actions) against "uniform-actions" with 3, 5, 9 and 17 actions: the
same learner (Sarsa(λ) on tile coding), only the action set differs. For each
task, configuration and seed: the learning curve (return per episode), the mean
return over the last 10% of the training episodes, a greedy evaluation (10
episodes), the number of actions at the end, environment steps and wall time.
Writes ``data/action_codebook.csv`` (one row per run) and
``figures/action_codebook.png`` under ``--out``, and prints the table.

    python benchmarks/action_codebook.py --out docs                  # docs/results/action-space.md
    python benchmarks/action_codebook.py --seeds 2 --scale 0.2 --out /tmp/a  # a quick look
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
from joblib import Parallel, delayed

#: task -> (training episodes, parameter overrides for every configuration)
TASKS = {
    "Pendulum-v1": (300, {}),
    # The registry's optimistic q_init (30) is what makes this task learnable: from 0 the agent
    # learns to stand still (return 0 beats the cost of pushing, -0.1 a^2) and never finds the flag.
    "MountainCarContinuous-v0": (100, {}),
}
#: configuration label -> (registered agent, overrides)
CONFIGS = {
    "adaptive (avq-actions)": ("avq-actions", {}),
    "uniform 3": ("uniform-actions", {"init_actions": 3}),
    "uniform 5": ("uniform-actions", {"init_actions": 5}),
    "uniform 9": ("uniform-actions", {"init_actions": 9}),
    "uniform 17": ("uniform-actions", {"init_actions": 17}),
}


def run_one(task: str, config: str, seed: int, episodes: int) -> dict:
    import gymnasium as gym

    import avq
    from avq.evaluation import evaluate_policy

    agent, overrides = CONFIGS[config]
    model = avq.make_agent(agent, gym.make(task), seed=seed, **{**TASKS[task][1], **overrides})
    t0 = time.perf_counter()
    model.learn(total_episodes=episodes)
    wall = time.perf_counter() - t0
    hist = model.episode_history()
    returns = np.asarray(hist["return"], float)
    ev = evaluate_policy(model, gym.make(task), n_eval_episodes=10, seed=10_000 + seed)
    return {
        "task": task,
        "config": config,
        "seed": seed,
        "episodes": episodes,
        "final_return": round(float(returns[-max(1, episodes // 10) :].mean()), 2),
        "greedy_return": round(ev["mean_return"], 2),
        "n_actions": int(model.n_actions_),
        "actions": " ".join(f"{v:.4g}" for v in np.sort(model.actions_.ravel())),
        "env_steps": int(model.num_timesteps),
        "wall_s": round(wall, 2),
        "curve": returns,
        "n_actions_curve": np.asarray(hist["n_cells"], float),
    }


def interval(values: list[float]) -> str:
    """``mean ± half-width of the 95% t-interval``."""
    from avq.plotting import mean_ci95

    mean, half = mean_ci95(np.asarray(values, float)[:, None])
    return f"{mean[0]:.1f} ± {half[0]:.1f}"


def plot(rows: list[dict], tasks: list[str], configs: list[str], seeds: int, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from avq.plotting import mean_ci95, running_mean

    fig, axes = plt.subplots(
        2, len(tasks), figsize=(6 * len(tasks), 7.5), squeeze=False, gridspec_kw={"height_ratios": [2, 1]}
    )
    for col, task in enumerate(tasks):
        top, bottom = axes[0, col], axes[1, col]
        for config in configs:
            runs = [r for r in rows if r["task"] == task and r["config"] == config]
            means = [running_mean(r["curve"], 10) for r in runs]
            mean, half = mean_ci95(np.stack([m for _, m in means]))
            x = means[0][0]
            style = {"color": "black", "lw": 2} if config.startswith("adaptive") else {"lw": 1}
            top.plot(x, mean, label=config, **style)
            top.fill_between(x, mean - half, mean + half, alpha=0.2, color=top.lines[-1].get_color())
            sizes = np.stack([r["n_actions_curve"] for r in runs])
            bottom.plot(np.arange(1, sizes.shape[1] + 1), sizes.mean(axis=0), label=config, **style)
        top.set_title(f"{task}\nreturn (10-episode mean; mean and 95% interval over {seeds} seeds)", fontsize=9)
        top.set_ylabel("return")
        top.grid(alpha=0.3)
        top.legend(fontsize=8)
        bottom.set_xlabel("episode")
        bottom.set_ylabel("actions (mean over seeds)")
        bottom.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every task's episode budget")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="docs")
    args = ap.parse_args()
    out = Path(args.out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    (out / "data").mkdir(parents=True, exist_ok=True)
    tasks, configs = list(TASKS), list(CONFIGS)
    jobs = [(t, c, s, max(2, int(TASKS[t][0] * args.scale))) for t in tasks for c in configs for s in range(args.seeds)]
    t0 = time.perf_counter()
    rows = Parallel(n_jobs=args.jobs)(delayed(run_one)(*j) for j in jobs)
    total = time.perf_counter() - t0

    cols = [k for k in rows[0] if not k.endswith("curve")]
    with open(out / "data" / "action_codebook.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in cols})
    plot(rows, tasks, configs, args.seeds, out / "figures" / "action_codebook.png")

    header = (
        "| task | actions | final return (last 10%) | greedy return (10 episodes) | actions at the end "
        "| env steps | s / run |"
    )
    lines = [header, "|---|---|---|---|---|---|---|"]
    for t in tasks:
        for c in configs:
            rs = [r for r in rows if r["task"] == t and r["config"] == c]
            n = np.array([r["n_actions"] for r in rs])
            lines.append(
                f"| {t} | {c} | {interval([r['final_return'] for r in rs])} | "
                f"{interval([r['greedy_return'] for r in rs])} | {np.median(n):.0f} [{n.min()}–{n.max()}] | "
                f"{np.mean([r['env_steps'] for r in rs]):.0f} | {np.mean([r['wall_s'] for r in rs]):.1f} |"
            )
    lines.append("")
    lines.append(
        f"{args.seeds} seeds per row (± is the half-width of the 95% t-interval over seeds); "
        f"total wall time {total:.0f} s with {args.jobs} processes."
    )
    print("\n".join(lines))


if __name__ == "__main__":
    main()
