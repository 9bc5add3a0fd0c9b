"""What a sweep leaves behind: ``results.csv`` (one row per trial), ``curves.png`` and the ranked report."""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from avq._io import atomic_write_bytes
from avq.sweep.config import METRICS, SweepConfig, _label
from avq.sweep.trial import Trial

__all__ = ["report"]


def _rows(cfg: SweepConfig, trials: list[Trial], results: dict[int, dict[str, Any]]) -> list[dict[str, Any]]:
    keys = list(cfg.grid)
    rows = []
    for t in trials:
        if t.index not in results:
            continue
        r = results[t.index]
        row: dict[str, Any] = {
            "trial": t.dirname,
            "config": t.config_id,
            "agent": t.agent,
            "seed_index": t.seed_index,
            "seed": t.seed,
        }
        row.update({f"config/{k}": t.point[k] for k in keys})
        row["status"] = r["status"]
        row.update({m: r.get(m) for m in METRICS})
        row["error"] = r.get("error", "")
        rows.append(row)
    return rows


def _write_results(out: Path, cfg: SweepConfig, rows: list[dict[str, Any]]) -> None:
    columns = [
        "trial",
        "config",
        "agent",
        "seed_index",
        "seed",
        *(f"config/{k}" for k in cfg.grid),
        "status",
        *METRICS,
        "error",
    ]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in columns})
    atomic_write_bytes(out / "results.csv", buf.getvalue().encode())


def _config_label(agent: str, point: dict[str, Any]) -> str:
    return f"{agent} {_label(point)}".strip()


def _plot_curves(out: Path, cfg: SweepConfig, trials: list[Trial], results: dict[int, dict[str, Any]]) -> bool:
    """Return per episode, mean and spread over seeds, one line per configuration (plot_learning_curves)."""
    from avq.plotting import plot_learning_curves

    curves: dict[str, list[np.ndarray]] = {}
    for t in trials:
        if results.get(t.index, {}).get("status") != "ok":
            continue
        path = out / "trials" / t.dirname / "progress.csv"
        with open(path, encoding="utf-8") as f:
            returns = np.array([float(r["return"]) for r in csv.DictReader(f)])
        curves.setdefault(_config_label(t.agent, t.point), []).append(returns)
    path = out / "curves.png"
    curves = {k: runs for k, runs in curves.items() if min(len(c) for c in runs) > 0}
    if not curves:
        if path.exists():
            path.unlink()  # a figure of an earlier state of the sweep would mislead
        return False
    # At most the 10 best configurations by the sweep's metric, so that the figure stays readable.
    note = ""
    if len(curves) > 10:
        higher = METRICS[cfg.metric]
        score: dict[str, list[float]] = {}
        for t in trials:
            value = results.get(t.index, {}).get(cfg.metric)
            if value is not None:
                score.setdefault(_config_label(t.agent, t.point), []).append(float(value))
        ranked = sorted(
            curves, key=lambda k: -np.mean(score.get(k, [-math.inf])) if higher else np.mean(score.get(k, [math.inf]))
        )
        curves = {k: curves[k] for k in ranked[:10]}
        note = f" (the 10 best of {len(ranked)} configurations by {cfg.metric})"
    # Each configuration is drawn over the episodes all its seeds have.
    plot_learning_curves(
        curves,
        path,
        ylabel="return per episode",
        xlabel="episode",
        title=f"{cfg.env}: return per episode{note}",
        higher_is_better=True,
    )
    return True


def report(out: str | os.PathLike, metric: str | None = None) -> str:
    """The configurations of a finished (or partial) sweep ranked by ``metric``, as a table.

    ``± 95%`` is the half-width of the t-interval of the mean over seeds; from fewer than
    ``MIN_SEEDS_FOR_INTERVAL`` (5) seeds it is marked ``*`` and a note says that it is wide, often
    wider than the range ``min``-``max`` beside it (over 2 seeds, 12.7 standard errors).
    """
    from avq.plotting import MIN_SEEDS_FOR_INTERVAL, mean_ci95

    out = Path(out)
    path = out / "results.csv"
    if not path.exists():
        raise ValueError(f"{out}: no results.csv here; is this a directory written by 'avq sweep'?")
    saved = json.loads((out / "sweep.json").read_text(encoding="utf-8")) if (out / "sweep.json").exists() else {}
    metric = metric or saved.get("metric", "final_return")
    if metric not in METRICS:
        raise ValueError(f"unknown metric {metric!r}; choose one of {', '.join(METRICS)}")
    with open(path, encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    groups: dict[str, dict[str, Any]] = {}
    for row in rows:
        label = " ".join([row["agent"], *(f"{k[7:]}={v}" for k, v in row.items() if k.startswith("config/"))])
        g = groups.setdefault(label, {"values": [], "failed": 0, "trials": 0})
        g["trials"] += 1
        if row["status"] != "ok":
            g["failed"] += 1
        elif row[metric] not in ("", None):
            g["values"].append(float(row[metric]))
    higher = METRICS[metric]
    ranked = []
    for label, g in groups.items():
        vals = np.array(g["values"])
        mean, half = mean_ci95(vals[:, None]) if len(vals) else (np.array([math.nan]), np.array([math.nan]))
        ranked.append((label, float(mean[0]), float(half[0]), vals, g))
    ranked.sort(key=lambda r: (math.isnan(r[1]), -r[1] if higher else r[1]))
    width = max([len("configuration")] + [len(r[0]) for r in ranked])
    head = f"{'rank':>4}  {'configuration':<{width}}  {metric + ' mean':>16}  {'± 95%':>9}  {'min':>9}  {'max':>9}  {'ok':>3}  {'failed':>6}"
    lines = [
        f"{out}: {len(rows)} trials, ranked by {metric} ({'higher' if higher else 'lower'} is better)",
        head,
        "-" * len(head),
    ]
    few = False
    for k, (label, mean_k, half_k, vals, g) in enumerate(ranked, 1):
        lo = f"{vals.min():.4g}" if len(vals) else "-"
        hi = f"{vals.max():.4g}" if len(vals) else "-"
        spread = f"{half_k:.3g}" if len(vals) >= 2 else "-"
        if 2 <= len(vals) < MIN_SEEDS_FOR_INTERVAL:
            spread += "*"
            few = True
        lines.append(
            f"{k:>4}  {label:<{width}}  {mean_k:>16.4g}  {spread:>9}  {lo:>9}  {hi:>9}  "
            f"{len(vals):>3}  {g['failed']:>6}"
        )
    if few:
        lines.append(
            f"* from fewer than {MIN_SEEDS_FOR_INTERVAL} seeds the 95% interval of the mean is wide (Student's t: "
            "12.7 standard errors over 2 seeds, 4.3 over 3), often wider than the range min-max: read min and max, "
            "or run more seeds"
        )
    return "\n".join(lines)
