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
        dist, _ = maze.lattice_distances()
        steps = maze.shortest_steps()
        # The path: steps - 1 moves at -1, then +10. An untried decision k moves away: k moves at -1, then 0.
        near = sum(1 for k in dist.ravel() if k >= 0 and -k > -(steps - 1) + 10)
        row = f"| {d} | {10**d:,} | {steps} ({9 * d}) | {near:,} ({near / 10**d:.0%}) |"
        assert row in out.stdout.splitlines()
        assert np.all(dist >= 0)  # (a drawn maze leads everywhere; the goal is one lattice point, reached from outside)


def test_lattice_beyond_its_limit_is_refused_with_the_fix():
    out = subprocess.run([sys.executable, str(SCRIPT), "--lattice", "--d", "8"], capture_output=True, text=True)
    assert out.returncode == 2 and "d = [8] has more than 2,000,000 lattice points; give d up to 6" in out.stderr
