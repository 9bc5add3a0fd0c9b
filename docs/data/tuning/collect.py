"""Gather the studies and sweeps of docs/results/tuning.md into CSVs and print the page's tables.

    python docs/data/tuning/collect.py WORK > docs/data/tuning_tables.md

WORK holds the two studies (WORK/tune-mc/study.db, WORK/tune-ac/study.db) and the sweeps
(WORK/heldout/NAME, NAME as the config file's stem; a sweep may be run in parts, NAME*, since each
seed's run is deterministic). Writes, next to this file, heldout.csv (one row per task, configuration
and seed, the held-out seeds and the study's own seeds) and trials.csv (one row per trial of the studies).
"""

from __future__ import annotations

import csv
import statistics
import sys
from pathlib import Path

HELD_OUT = [
    ("MountainCar-v0", "tuned", "mc-tuned"),
    ("MountainCar-v0", 'current entry = general ("*")', "mc-general"),
    ("Acrobot-v1", "tuned", "ac-tuned"),
    ("Acrobot-v1", "current entry (Acrobot-v1)", "ac-entry"),
    ("Acrobot-v1", 'general ("*")', "ac-general"),
]
TUNING_SEEDS = [
    ("MountainCar-v0", 'current entry = general ("*")', "mc-general-tuningseeds", "tune-mc", "avq-MountainCar-v0"),
    ("Acrobot-v1", "current entry (Acrobot-v1)", "ac-entry-tuningseeds", "tune-ac", "avq-Acrobot-v1"),
]
COLS = ["final_return", "eval_return", "success_rate", "n_cells", "env_steps", "wall_s"]


def sweep_rows(work: Path, name: str) -> list[dict]:
    rows = []
    for path in sorted(work.glob(f"heldout/{name}*/results.csv")):
        if path.parent.name != name and not path.parent.name.startswith(f"{name}-"):
            continue
        if path.parent.name.endswith("tuningseeds") != name.endswith("tuningseeds"):
            continue
        with open(path, newline="") as f:
            rows += [r for r in csv.DictReader(f) if r["status"] == "ok"]
    return rows


def spread(values: list[float]) -> str:
    sd = statistics.stdev(values) if len(values) > 1 else 0.0
    return (
        f"{statistics.mean(values):.1f} ± {sd:.1f} | {min(values):.1f} | {statistics.median(values):.1f} "
        f"| {max(values):.1f}"
    )


def main(work: Path) -> None:
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    here = Path(__file__).parent
    rows = []
    for task, label, name in HELD_OUT:
        rows += [
            {
                "task": task,
                "configuration": label,
                "seeds": "held out",
                "seed": int(r["seed"]),
                **{c: float(r[c]) for c in COLS},
            }
            for r in sweep_rows(work, name)
        ]
    for task, label, name, _, _ in TUNING_SEEDS:
        rows += [
            {
                "task": task,
                "configuration": label,
                "seeds": "the study's",
                "seed": int(r["seed"]),
                **{c: float(r[c]) for c in COLS},
            }
            for r in sweep_rows(work, name)
        ]
    with open(here / "heldout.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["task", "configuration", "seeds", "seed", *COLS])
        w.writeheader()
        w.writerows(rows)

    print("Held-out seeds, 500 episodes a run:\n")
    print(
        "| task | configuration | seeds | final return, mean ± sd | min | median | max "
        "| greedy return (median) | greedy success (mean) | cells (median) | env steps (median) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for task, label, _ in HELD_OUT:
        rs = [r for r in rows if r["task"] == task and r["configuration"] == label and r["seeds"] == "held out"]
        if rs:
            print(
                f"| {task} | {label} | {len(rs)} | {spread([r['final_return'] for r in rs])} "
                f"| {statistics.median(r['eval_return'] for r in rs):.1f} "
                f"| {100 * statistics.mean(r['success_rate'] for r in rs):.0f}% "
                f"| {statistics.median(r['n_cells'] for r in rs):.0f} "
                f"| {statistics.median(r['env_steps'] for r in rs):,.0f} |"
            )

    seeds = sorted({r["seed"] for r in rows if r["seeds"] == "held out"})
    print("\nFinal return of each held-out seed:\n")
    print("| task | configuration | " + " | ".join(str(s) for s in seeds) + " |")
    print("|---|---|" + "---|" * len(seeds))
    for task, label, _ in HELD_OUT:
        by = {
            r["seed"]: r["final_return"]
            for r in rows
            if r["task"] == task and r["configuration"] == label and r["seeds"] == "held out"
        }
        if by:
            print(f"| {task} | {label} | " + " | ".join(f"{by[s]:.1f}" if s in by else "–" for s in seeds) + " |")

    print("\nTuned against the current entry, seed by seed (tuned minus current; higher is better for tuned):\n")
    print("| task | mean difference | tuned ahead on |")
    print("|---|---|---|")
    for (task, tuned, _), (_, current, _) in ((HELD_OUT[0], HELD_OUT[1]), (HELD_OUT[2], HELD_OUT[3])):
        a = {
            r["seed"]: r["final_return"]
            for r in rows
            if r["task"] == task and r["configuration"] == tuned and r["seeds"] == "held out"
        }
        b = {
            r["seed"]: r["final_return"]
            for r in rows
            if r["task"] == task and r["configuration"] == current and r["seeds"] == "held out"
        }
        both = sorted(set(a) & set(b))
        if both:
            d = [a[s] - b[s] for s in both]
            print(f"| {task} | {statistics.mean(d):+.1f} | {sum(x > 0 for x in d)} of {len(d)} seeds |")

    trials = []
    print("\nThe studies:\n")
    print(
        "| task | budget of a trial | trials (complete, pruned) | env steps, all trials | wall time "
        "| best trial on the study's seeds | current entry on the study's seeds |"
    )
    print("|---|---|---|---|---|---|---|")
    for task, _label, name, study_dir, study_name in TUNING_SEEDS:
        db = work / study_dir / "study.db"
        if not db.exists():
            continue
        study = optuna.load_study(study_name=study_name, storage=f"sqlite:///{db}")
        ts = study.trials
        for t in ts:
            trials.append(
                {
                    "task": task,
                    "trial": t.number,
                    "state": t.state.name.lower(),
                    "value": "" if t.value is None else round(t.value, 3),
                    "env_steps": t.user_attrs.get("env_steps"),
                    "seed_values": " ".join(f"{v:.2f}" for v in t.user_attrs.get("seed_values") or []),
                    "seconds": round((t.datetime_complete - t.datetime_start).total_seconds(), 1),
                    **{f"param/{k}": v for k, v in t.params.items()},
                }
            )
        a = study.user_attrs
        done = [t for t in ts if t.state.name == "COMPLETE"]
        best = study.best_trial
        wall = (max(t.datetime_complete for t in ts) - min(t.datetime_start for t in ts)).total_seconds()
        steps = sum(t.user_attrs["env_steps"] for t in ts)
        base = [float(r["final_return"]) for r in sweep_rows(work, name)]
        base_s = f"{statistics.mean(base):.1f} ({min(base):.1f} to {max(base):.1f})" if base else "–"
        bv = best.user_attrs["seed_values"]
        print(
            f"| {task} | {len(a['seeds'])} seeds × {a['episodes']} episodes, {a['evaluations']} evaluations "
            f"| {len(ts)} ({len(done)}, {len(ts) - len(done)}) | {steps:,} | {wall / 60:.1f} min "
            f"| trial {best.number}: {best.value:.1f} ({min(bv):.1f} to {max(bv):.1f}) | {base_s} |"
        )
    keys = sorted({k for t in trials for k in t})
    order = ["task", "trial", "state", "value", "env_steps", "seconds", "seed_values"]
    with open(here / "trials.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=order + [k for k in keys if k not in order])
        w.writeheader()
        w.writerows(trials)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
