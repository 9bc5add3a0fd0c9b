"""benchmarks/scaling.py --plot: the figure and the table drawn again from the family's CSV, which is left as it is."""

import csv
import importlib.util
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = str(ROOT / "benchmarks" / "scaling.py")
SPEC = importlib.util.spec_from_file_location("scaling", SCRIPT)
scaling = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(scaling)


def _plot(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, SCRIPT, "--robot", "--plot", *args], cwd=cwd, capture_output=True, text=True)


def test_plot_redraws_from_the_csv_without_running_or_rewriting_it(tmp_path):
    data = tmp_path / "docs" / "data"
    data.mkdir(parents=True)
    rows = [
        {"agent": a, "size": m, "states": int(98 / m**2), "slip": 0.0, "seed": s, "reached": steps < 1_000_000,
         "env_steps": steps, "cells": 10 * (s + 1), "success": 1.0, "backups": 0, "wall_s": 1.0}
        for a, base in (("avq", 1_000), ("tiles", 3_000))
        for m in (0.5, 0.25, 0.125)
        for s, steps in enumerate((base, 2 * base, 1_000_001 if a == "tiles" and m == 0.125 else 3 * base))
    ]  # fmt: skip
    with open(data / "scaling_robot.csv", "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=scaling.FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    before = (data / "scaling_robot.csv").read_bytes()
    out = _plot(tmp_path, "--seeds", "3")
    assert out.returncode == 0, out.stderr
    assert (data / "scaling_robot.csv").read_bytes() == before
    assert (tmp_path / "docs" / "figures" / "scaling_robot.png").stat().st_size > 10_000
    lines = out.stdout.splitlines()
    # the medians of the three seeds, the runs that reached 95% and the median cells, per agent and move
    assert any(line.split()[:3] == ["0.5", "392", "avq"] and "2,000 [1,000-3,000]" in line and "3/3" in line
               and line.split()[-1] == "20" for line in lines)  # fmt: skip
    assert any(line.split()[:3] == ["0.125", "6272", "tiles"] and "6,000 [3,000-1,000,001]" in line and "2/3" in line
               for line in lines)  # fmt: skip
    assert out.stdout.rstrip().endswith("wrote docs/figures/scaling_robot.png")


def test_plot_without_runs_says_what_to_do_and_exits_2(tmp_path):
    out = _plot(tmp_path)
    assert out.returncode == 2
    assert "--plot: no runs of 0.5, 0.25, 0.125 in docs/data/scaling_robot.csv; run the study first" in out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "docs").exists()
