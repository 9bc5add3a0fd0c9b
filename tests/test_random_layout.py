"""The seeded maze generator."""

import gymnasium as gym
import numpy as np
import pytest

from avq.envs import parse_layout, random_layout


def test_same_seed_same_maze_and_seeds_differ():
    assert random_layout(14, 12, 0.3, seed=5) == random_layout(14, 12, 0.3, seed=5)
    assert len({tuple(random_layout(14, 12, 0.3, seed=s)) for s in range(10)}) == 10


@pytest.mark.parametrize("seed", range(20))
def test_mazes_are_bordered_connected_and_near_the_density(seed):
    rows = random_layout(13, 13, 0.2, seed=seed)
    lay = parse_layout(rows)
    assert lay.walls[0].all() and lay.walls[-1].all() and lay.walls[:, 0].all() and lay.walls[:, -1].all()
    free = ~lay.walls
    assert (lay.distances[free] >= 0).all()  # every free square reaches the goal
    assert sum(r.count("G") for r in rows) == 1 and lay.start is None
    inner = lay.walls[1:-1, 1:-1]
    assert abs(inner.mean() - 0.2) <= 0.02 and 90 <= lay.n_states <= 100


def test_a_generated_maze_is_an_environment():
    env = gym.make("avq/GridMaze-v0", layout=random_layout(10, 9, 0.25, seed=1))
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    robot = gym.make("avq/RobotMaze-v0", layout=random_layout(10, 9, 0.25, seed=1))
    assert robot.reset(seed=0)[0].shape == (2,)


def test_large_mazes_reach_their_density():
    lay = parse_layout(random_layout(60, 60, 0.3, seed=0))
    assert abs(lay.walls[1:-1, 1:-1].mean() - 0.3) < 0.01 and (lay.distances[~lay.walls] >= 0).all()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        ((2, 10, 0.2), "width must be an integer >= 3"),
        ((10, 1.5, 0.2), "height"),
        ((10, 10, 0.9), "wall_density must be a number in"),
        ((10, 10, -0.1), "wall_density"),
    ],
)
def test_bad_arguments(args, needle):
    with pytest.raises(ValueError, match=needle):
        random_layout(*args)


def test_zero_density_is_an_open_room():
    lay = parse_layout(random_layout(6, 5, 0.0, seed=0))
    assert lay.n_states == 12 and np.array_equal(lay.walls[1:-1, 1:-1], np.zeros((3, 4), bool))


# -- refine_layout: the same maze at k times the resolution --------------------------------------------


def test_refine_layout_by_hand():
    from avq.envs import refine_layout

    assert refine_layout(["#S", ".G"], 1) == ["#S", ".G"]
    # k = 3: each square a 3 x 3 block; S and G at the centre (1, 1) of their blocks.
    assert refine_layout(["#S", ".G"], 3) == [
        "###...",
        "###.S.",
        "###...",
        "......",
        "....G.",
        "......",
    ]
    for bad in (0, -1, 2.0, True):
        with pytest.raises(ValueError, match="k must be an integer >= 1"):
            refine_layout(["#S", ".G"], bad)


@pytest.mark.parametrize("k", [2, 4])
def test_refined_lau2002_has_k_squared_the_squares_and_at_most_k_times_the_distances(k):
    from avq.envs import load_layout, refine_layout

    base, fine = load_layout("lau2002"), load_layout(refine_layout("lau2002", k))
    assert fine.n_states == k * k * base.n_states
    assert np.array_equal(fine.walls, np.kron(base.walls, np.ones((k, k), dtype=bool)))
    for x, y in base.free_positions():
        # From the centre square of a block to the goal: at most k times the coarse distance (the coarse
        # path, k squares a move; the fine path may cut corners inside blocks, so it can be shorter).
        d = fine.distances[y * k + k // 2, x * k + k // 2]
        assert 0 < d <= k * base.distances[y, x]
