"""Soak run: does the ``avq`` agent stay bounded over millions of steps on RobotMaze?

Trains ``avq.AVQSarsa(gymnasium.make("avq/RobotMaze-v0"), seed=SEED, **avq.AGENTS["avq-sarsa"][1])``
(the general Sarsa(λ) agent, with the value-change trigger, rather than the maze rules ``avq`` takes there)
by calling ``agent.learn(total_timesteps=EVERY)`` again and again (``learn`` continues where it stopped) and, after every call, records:

- primitive steps and finished episodes so far, wall seconds, steps per second of the chunk;
- the process's resident memory in MB: current (``/proc/self/statm``), peak (``VmHWM``) and
  anonymous (``RssAnon``: heap and arrays, without the mapped files of libraries and compiled code);
- what the agent itself holds: its per-episode history (logical bytes, 9 float64 per
  episode, and the bytes allocated for it) and its codebook-sized arrays;
- the codebook size ``agent.n_cells`` (the bound is ``agent.max_cells``);
- min and max of ``agent.q_`` and whether every value is finite;
- appends, merges and refused appends so far, and the mean return and success rate
  (goal reached before the step limit) of the episodes finished in the chunk.

It writes one CSV row per checkpoint, draws a 4-panel figure against steps (memory,
cells, value range, return and success) and prints a table and a verdict: memory growth
over the second half of the run, the largest codebook, whether values stayed finite.

Everything but the wall times and memory figures is a function of ``--seed``.
Matplotlib is imported only after the run, so it does not count in the memory figures.

    python benchmarks/soak.py                    # 2,000,000 steps, checkpoints every 50,000
    python benchmarks/soak.py --quick            # 100,000 steps, checkpoints every 5,000
    python benchmarks/soak.py --steps 50000000 --every 1000000 --csv /tmp/s.csv --figure /tmp/s.png

By default it writes docs/data/soak.csv and docs/figures/soak.png (``--no-files``: print only).
MB here means 2**20 bytes. Results of a run are described in docs/results/soak.md.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import resource
import sys
import time
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np

import avq

ROOT = Path(__file__).resolve().parents[1]
ENV_ID = "avq/RobotMaze-v0"
AGENT = "avq-sarsa"
MB = 1024.0 * 1024.0
PAGE = os.sysconf("SC_PAGE_SIZE")

COLUMNS = (
    "steps",
    "episodes",
    "wall_s",
    "chunk_steps_per_s",
    "rss_mb",
    "peak_rss_mb",
    "rss_anon_mb",
    "history_mb",
    "history_alloc_mb",
    "agent_arrays_mb",
    "n_cells",
    "max_cells",
    "q_min",
    "q_max",
    "finite",
    "appends",
    "merges",
    "refused",
    "chunk_episodes",
    "chunk_mean_return",
    "chunk_success",
)


def rss_bytes() -> int:
    """Current resident set size of this process (0 where ``/proc`` is missing)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * PAGE
    except OSError:
        return 0


def proc_status_bytes(field: str) -> int | None:
    """A ``kB`` field of ``/proc/self/status`` (``VmHWM``, ``RssAnon``) in bytes; None if unavailable."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def peak_rss_bytes() -> int:
    """Peak resident set size so far: ``VmHWM``, the same counter as ``statm``'s resident size.

    (``getrusage``'s ``ru_maxrss`` is the fallback; on Linux it lags ``VmHWM`` by a few hundred KB.)
    """
    peak = proc_status_bytes("VmHWM")
    if peak is not None:
        return peak
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak if sys.platform == "darwin" else peak * 1024


def history_bytes(agent) -> tuple[int, int]:
    """(bytes the finished episodes need, bytes allocated for them) of the per-episode history.

    The allocation is read from the history's private buffer, for accounting only.
    """
    n = len(agent.history_)
    data = getattr(agent.history_, "_data", None)
    width = data.shape[1] if data is not None else 9
    return n * width * 8, (data.nbytes if data is not None else n * width * 8)


def agent_array_bytes(agent) -> int:
    """Bytes of the agent's codebook-sized arrays (private attributes, for accounting only)."""
    names = ("_V", "_Q", "_E", "_born", "_act", "_pc")
    return sum(getattr(agent, k).nbytes for k in names if isinstance(getattr(agent, k, None), np.ndarray))


def soak(steps: int, every: int, seed: int) -> tuple[list[dict], dict]:
    env = gym.make(ENV_ID)
    # The general Sarsa(λ) defaults (value-change trigger; unbounded growth is what a soak should exercise),
    # not the planning agent that make_agent("avq", RobotMaze) is.
    agent = avq.AVQSarsa(env, seed=seed, **avq.AGENTS[AGENT][1])
    info = {
        "max_cells": agent.max_cells,
        "value_trigger": agent.value_trigger,
        "max_steps": int(env.unwrapped.max_steps),
        "rss_before_mb": rss_bytes() / MB,
    }
    rows: list[dict] = []
    t_start = time.perf_counter()
    done = 0
    while done < steps:
        chunk = min(every, steps - done)
        t = time.perf_counter()
        agent.learn(total_timesteps=chunk)
        dt = time.perf_counter() - t
        done += chunk
        q = agent.q_
        finite = bool(np.isfinite(q).all())
        hist, hist_alloc = history_bytes(agent)
        rows.append(
            {
                "steps": agent.num_timesteps,
                "episodes": agent.num_episodes,
                "wall_s": time.perf_counter() - t_start,
                "chunk_steps_per_s": chunk / dt if dt > 0 else float("inf"),
                "rss_mb": rss_bytes() / MB,
                "peak_rss_mb": peak_rss_bytes() / MB,
                "rss_anon_mb": (proc_status_bytes("RssAnon") or 0) / MB,
                "history_mb": hist / MB,
                "history_alloc_mb": hist_alloc / MB,
                "agent_arrays_mb": agent_array_bytes(agent) / MB,
                "n_cells": agent.n_cells,
                "max_cells": agent.max_cells,
                "q_min": float(np.nanmin(q)) if q.size and not np.isnan(q).all() else float("nan"),
                "q_max": float(np.nanmax(q)) if q.size and not np.isnan(q).all() else float("nan"),
                "finite": finite,
            }
        )
        if done != agent.num_timesteps:
            raise RuntimeError(
                f"learn is not additive: asked for {done} steps in all, the agent counts {agent.num_timesteps}"
            )
    info["total_wall_s"] = time.perf_counter() - t_start
    add_episode_figures(rows, agent.episode_history(), info["max_steps"])
    info["num_episodes"] = agent.num_episodes
    return rows, info


def add_episode_figures(rows: list[dict], hist: dict[str, np.ndarray], max_steps: int) -> None:
    """Cumulative appends/merges/refused and per-chunk return and success, from the final history.

    Read once at the end (not at every checkpoint), so that copying the history does not
    enter the memory figures. Counts cover the episodes finished by each checkpoint.
    Success is an episode shorter than the step limit (a goal reached exactly on the
    last allowed step counts as a failure: the history does not say which it was).
    """
    n = len(hist.get("episode", ()))
    cum = {
        k: np.concatenate([[0], np.cumsum(hist[k])]) if n else np.zeros(1, dtype=np.int64)
        for k in ("appends", "merges", "refused")
    }
    prev = 0
    for row in rows:
        e = row["episodes"]
        for k in cum:
            row[k] = int(cum[k][e])
        row["chunk_episodes"] = e - prev
        if e > prev:
            row["chunk_mean_return"] = float(hist["return"][prev:e].mean())
            row["chunk_success"] = float((hist["steps"][prev:e] < max_steps).mean())
        else:
            row["chunk_mean_return"] = row["chunk_success"] = float("nan")
        prev = e


def write_csv(rows: list[dict], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, lineterminator="\n")
        w.writeheader()
        for row in rows:
            w.writerow(
                {
                    k: (f"{v:.6g}" if isinstance(v, float) else int(v) if isinstance(v, bool) else v)
                    for k, v in row.items()
                }
            )


def draw(rows: list[dict], info: dict, seed: int, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = np.array([r["steps"] for r in rows]) / 1e6
    col = {k: np.array([r[k] for r in rows], dtype=float) for k in COLUMNS}
    fig, axes = plt.subplots(4, 1, figsize=(7.5, 9.5), sharex=True)
    ax = axes[0]
    for key, style, label in (
        ("rss_mb", "-", "RSS"),
        ("peak_rss_mb", "--", "peak RSS"),
        ("rss_anon_mb", "-.", "anonymous RSS"),
        ("history_mb", ":", "episode history written"),
    ):
        ax.plot(x, col[key] - col[key][0], style, label=label)
    ax.set_ylabel("MB since the\nfirst checkpoint")
    ax.set_title(
        f"memory: RSS {col['rss_mb'][0]:.1f} MB at the first checkpoint, {col['rss_mb'][-1]:.1f} MB "
        f"at the last (peak {col['peak_rss_mb'][-1]:.1f} MB)",
        fontsize=9,
    )
    ax.legend(fontsize=8, loc="upper left")
    ax = axes[1]
    ax.plot(x, col["n_cells"], color="C2")
    ax.set_ylabel("cells")
    ax.set_title(
        f"codebook size (max_cells = {info['max_cells']}, refused appends: {int(col['refused'][-1])})", fontsize=9
    )
    ax = axes[2]
    ax.plot(x, col["q_max"], color="C1", label="max Q")
    ax.plot(x, col["q_min"], color="C3", label="min Q")
    ax.set_ylabel("action value")
    ax.legend(fontsize=8)
    ax = axes[3]
    ax.plot(x, col["chunk_mean_return"], color="C4")
    ax.set_ylabel("mean return\n(per checkpoint)", color="C4")
    ax2 = ax.twinx()
    ax2.plot(x, 100 * col["chunk_success"], color="C5", alpha=0.8)
    ax2.set_ylabel("success (%)", color="C5")
    ax2.set_ylim(0, 100)
    ax.set_xlabel("environment steps (millions)")
    fig.suptitle(f"Soak: agent {AGENT!r} on {ENV_ID}, seed {seed}, {rows[-1]['steps']:,} steps")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def pick(rows: list[dict], k: int = 8) -> list[dict]:
    """About ``k`` checkpoints spread over the run, first and last included."""
    idx = sorted(set(np.linspace(0, len(rows) - 1, min(k, len(rows))).round().astype(int)))
    return [rows[i] for i in idx]


def print_table(rows: list[dict]) -> None:
    head = (
        f"{'steps':>11} {'episodes':>9} {'wall s':>7} {'RSS MB':>7} {'peak MB':>8} {'anon MB':>8} {'hist buf':>8} "
        f"{'cells':>6} {'Q min':>9} {'Q max':>8} {'finite':>6} {'refused':>7} {'return':>8} {'succ %':>6}"
    )
    print(head)
    for r in rows:
        print(
            f"{r['steps']:>11,} {r['episodes']:>9,} {r['wall_s']:>7.2f} {r['rss_mb']:>7.1f} "
            f"{r['peak_rss_mb']:>8.1f} {r['rss_anon_mb']:>8.1f} {r['history_alloc_mb']:>8.2f} {r['n_cells']:>6} {r['q_min']:>9.2f} "
            f"{r['q_max']:>8.2f} {str(r['finite']):>6} {r['refused']:>7} {r['chunk_mean_return']:>8.1f} "
            f"{100 * r['chunk_success']:>6.1f}"
        )


def verdict(rows: list[dict], info: dict) -> list[str]:
    total = rows[-1]["steps"]
    half = next(r for r in rows if r["steps"] >= total / 2)
    last = rows[-1]
    grow = last["rss_mb"] - half["rss_mb"]
    anon_grow = last["rss_anon_mb"] - half["rss_anon_mb"]
    pct = 100 * grow / half["rss_mb"] if half["rss_mb"] else float("nan")
    hist_grow = last["history_alloc_mb"] - half["history_alloc_mb"]
    hist_need = last["history_mb"] - half["history_mb"]
    agent_grow = last["agent_arrays_mb"] - half["agent_arrays_mb"]
    # The history buffer is zero-filled on allocation, so only the rows written so far are resident:
    # the bytes needed, not the bytes allocated, are what RSS should follow.
    other = grow - hist_need - agent_grow
    max_cells = max(r["n_cells"] for r in rows)
    cells_half = max(r["n_cells"] for r in rows if r["steps"] <= half["steps"])
    finite = all(r["finite"] for r in rows)
    eps_half = last["episodes"] - half["episodes"]
    lines = [
        f"memory: RSS {half['rss_mb']:.1f} MB at {half['steps']:,} steps -> {last['rss_mb']:.1f} MB at "
        f"{last['steps']:,}: {grow:+.2f} MB ({pct:+.2f}%) over the second half; peak {last['peak_rss_mb']:.1f} MB; "
        f"anonymous RSS {anon_grow:+.2f} MB",
        f"        episode history: {hist_need:+.2f} MB written ({eps_half:,} episodes x 72 B; its buffer, "
        f"grown by doubling, {hist_grow:+.2f} MB); codebook arrays {agent_grow:+.3f} MB; "
        f"RSS growth not explained by these: {other:+.2f} MB",
        f"cells:  max {max_cells} (by the half-way point: {cells_half}; final {last['n_cells']}); "
        f"max_cells = {info['max_cells']}; refused appends: {last['refused']}",
        f"values: Q in [{last['q_min']:.2f}, {last['q_max']:.2f}] at the end; "
        f"{'all finite at every checkpoint' if finite else 'NOT FINITE at some checkpoint'}",
    ]
    mem_ok = abs(other) <= max(2.0, 0.01 * half["rss_mb"])
    lines.append(
        "verdict: memory "
        + (
            "bounded apart from the per-episode history (which grows linearly by design)"
            if mem_ok
            else "grows beyond what the history explains: investigate"
        )
        + "; codebook "
        + (
            f"bounded ({max_cells} cells at most, {100 * max_cells / info['max_cells']:.1f}% of "
            f"max_cells; {last['n_cells'] - half['n_cells']:+d} over the second half)"
            if max_cells < info["max_cells"] and last["refused"] == 0
            else "at its max_cells bound (appends refused)"
        )
        + ("; values finite" if finite else "; values NOT finite")
    )
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=None, help="primitive steps in all (default 2,000,000)")
    ap.add_argument("--every", type=int, default=None, help="steps per learn() call and checkpoint (default 50,000)")
    ap.add_argument("--quick", action="store_true", help="100,000 steps, checkpoints every 5,000")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--csv", type=Path, default=ROOT / "docs" / "data" / "soak.csv")
    ap.add_argument("--figure", type=Path, default=ROOT / "docs" / "figures" / "soak.png")
    ap.add_argument("--no-files", action="store_true", help="print only; write no CSV or figure")
    args = ap.parse_args(argv)
    steps = args.steps if args.steps is not None else (100_000 if args.quick else 2_000_000)
    every = args.every if args.every is not None else (5_000 if args.quick else 50_000)
    if steps < 1 or every < 1:
        ap.error("--steps and --every must be >= 1")

    print(f"soak: agent {AGENT!r} on {ENV_ID}, seed {args.seed}, {steps:,} steps, checkpoint every {every:,}")
    print(
        f"machine: {os.cpu_count()} CPUs, {platform.python_implementation()} {platform.python_version()}, "
        f"NumPy {np.__version__}, Numba {numba.__version__}, Gymnasium {gym.__version__}, "
        f"avq {avq.__version__}, {platform.platform()}"
    )
    rows, info = soak(steps, every, args.seed)
    print(
        f"max_cells = {info['max_cells']}, value_trigger = {info['value_trigger']}, "
        f"episode step limit = {info['max_steps']}; RSS before learning {info['rss_before_mb']:.1f} MB"
    )
    print(
        f"run: {info['total_wall_s']:.1f} s for {rows[-1]['steps']:,} steps and {info['num_episodes']:,} "
        f"episodes ({rows[-1]['steps'] / info['total_wall_s']:,.0f} steps/s including the first call's "
        f"compilation; {rows[0]['wall_s']:.1f} s to the first checkpoint)"
    )
    print()
    print_table(pick(rows, 10))
    print()
    for line in verdict(rows, info):
        print(line)
    if not args.no_files:
        write_csv(rows, args.csv)
        draw(rows, info, args.seed, args.figure)
        print(f"\nwrote {args.csv} and {args.figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
