"""benchmarks/dimensions.py --lattice: what an explorer of the slab maze's lattice of moves faces at each d."""

import subprocess
import sys
from pathlib import Path

import numpy as np

from avq.envs import SlabMaze

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "dimensions.py"


def test_lattice_prints_the_goals_distance_and_the_points_whose_untried_decisions_outbid_it():
    out = subprocess.run([sys.executable, str(SCRIPT), "--lattice", "--d", "2,3"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    for d in (2, 3):
        maze = SlabMaze(dims=d, layout_seed=d, start="fixed")
        dist, pts = maze.lattice_distances()
        steps = maze.shortest_steps()
        # The path: steps - 1 moves at -1, then +10. An untried decision k moves away: k moves at -1, then 0.
        near = sum(1 for k in dist.ravel() if k >= 0 and -k > -(steps - 1) + 10)
        # Told the goal's distance: moves from the start plus distance to the goal (0.9 less each coordinate,
        # over 0.1), at most the goal's moves.
        ahead = sum(
            1
            for idx in np.ndindex(dist.shape)
            if dist[idx] >= 0
            and dist[idx] + sum(max(0.0, 0.9 - pts[k][i]) / 0.1 for k, i in enumerate(idx)) <= steps + 1e-9
        )
        row = (
            f"| {d} | {10**d:,} | {steps} ({9 * d}) | {near:,} ({near / 10**d:.0%}) | {ahead:,} ({ahead / 10**d:.0%}) "
            "| 100% |"  # (200,000 env steps stand on far more points than the lattice has)
        )
        assert row in out.stdout.splitlines()
        assert np.all(dist >= 0)  # (a drawn maze leads everywhere; the goal is one lattice point, reached from outside)


def test_lattice_bounds_the_goals_places_any_explorer_finds_within_the_budget():
    # 49 moves stand on at most 50 of d = 2's 100 lattice points: whatever an explorer does before its first +10
    # is the same wherever the goal is, so it finds at most half of the goal's places; 19 moves, a fifth.
    for budget, share in ((49, "50%"), (19, "20%"), (100, "100%")):
        out = subprocess.run(
            [sys.executable, str(SCRIPT), "--lattice", "--d", "2", "--budget", str(budget)],
            capture_output=True,
            text=True,
        )
        assert out.returncode == 0, out.stderr
        header, _, row = out.stdout.splitlines()[:3]
        assert header.endswith(f"| places found within {budget:,}, at most |")
        assert row.startswith("| 2 | 100 |") and row.endswith(f"| {share} |")


def test_lattice_beyond_its_limit_is_refused_with_the_fix():
    out = subprocess.run([sys.executable, str(SCRIPT), "--lattice", "--d", "8"], capture_output=True, text=True)
    assert out.returncode == 2 and "d = [8] has more than 2,000,000 lattice points; give d up to 6" in out.stderr


def run_dims(out: Path, *extra: str) -> list[str]:
    """The avq row of ``--dims`` at d = 2 from the fixed start, seed 0, 5,000 env steps, as CSV fields."""
    args = ["--dims", "--start", "fixed", "--agents", "avq", "--d", "2", "--seeds", "0-0", "--budget", "5000"]
    done = subprocess.run(
        [sys.executable, str(SCRIPT), *args, *extra, "--jobs", "1", "--out", str(out)], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    (csv,) = (out / "data").iterdir()
    return [csv.name, done.stdout, *csv.read_text().splitlines()[1].split(",")]


def test_shaped_runs_tell_the_agent_the_goals_distance_and_write_their_own_csv(tmp_path):
    name, stdout, *shaped = run_dims(tmp_path / "shaped", "--shaped")
    assert name == "dimensions_fixed_shaped.csv"
    assert "1 runs: SlabMaze shaped by the goal's distance d [2], seeds [0]" in stdout
    assert shaped[:2] == ["avq", "2"] and shaped[4] == "True"
    name, _, *plain = run_dims(tmp_path / "plain")
    assert name == "dimensions_fixed.csv" and plain[4] == "True"
    assert int(shaped[5]) < int(plain[5])  # (env steps to the goal: the same seed, told where the goal is)


def test_dims_without_agents_runs_the_studys_and_names_every_variant_when_one_is_unknown(tmp_path):
    args = ["--dims", "--start", "fixed", "--d", "2", "--seeds", "0-0", "--budget", "200", "--jobs", "1"]
    done = subprocess.run([sys.executable, str(SCRIPT), *args, "--out", str(tmp_path)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rows = (tmp_path / "data" / "dimensions_fixed.csv").read_text().splitlines()[1:]
    # The first section's agents only: the variants (avq-known1, avq-goal10, avq-unsettled) run when named.
    assert [row.split(",")[0] for row in rows] == ["avq", "avq-sarsa", "tiles", "grid-ps", "avq-axis"]
    bad = subprocess.run([sys.executable, str(SCRIPT), "--dims", "--agents", "avq-x"], capture_output=True, text=True)
    assert bad.returncode == 2
    assert (
        "--agents avq-x: choose from avq, avq-sarsa, tiles, grid-ps, avq-axis, avq-known1, avq-goal10, "
        "avq-unsettled, dqn" in bad.stderr
    )
