"""Tests for the grid maze environment and its layouts (SPEC §6)."""

from __future__ import annotations

import warnings
from collections import Counter

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import avq  # noqa: F401  (registers avq/GridMaze-v0)
from avq.envs import MAPS, GridMaze, load_layout, parse_layout
from avq.envs.grid_maze import EAST, NORTH, SOUTH, WEST

# A small hand-made layout. Walls at (2, 0) and (2, 1); goal at (4, 1); S at (0, 0).
#
#        x: 0 1 2 3 4
#   y = 0:  S . # . .
#   y = 1:  . . # . G
#   y = 2:  . . . . .
SMALL = [
    "S.#..",
    "..#.G",
    ".....",
]
# Shortest-path steps to the goal, worked out by hand; -1 on walls.
SMALL_DIST = np.array(
    [
        [7, 6, -1, 2, 1],
        [6, 5, -1, 1, 0],
        [5, 4, 3, 2, 1],
    ]
)

# The reference maze as drawn in SPEC §6.
LAU2002 = [
    "##############",
    "#S...........#",
    "#............#",
    "#..#######...#",
    "#........#...#",
    "#........#.#.#",
    "#..#.....#.#.#",
    "#..#.....#.#G#",
    "#..#.....###.#",
    "#..#.........#",
    "#..#.........#",
    "##############",
]


def pos(obs: np.ndarray) -> tuple[float, float]:
    return float(obs[0]), float(obs[1])


# -- 1. Gymnasium's env checker -----------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"render_mode": "ansi"},
        {"render_mode": "rgb_array"},
        {"start": "fixed"},
        {"layout": SMALL, "render_mode": "ansi"},
    ],
    ids=["default", "ansi", "rgb_array", "fixed", "small-ansi"],
)
def test_check_env_passes_without_warnings(kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make("avq/GridMaze-v0", **kwargs)
        assert isinstance(env.unwrapped, GridMaze)
        check_env(env.unwrapped)
        env.close()


# -- 2. Registration and the 100-step limit ---------------------------------------------


def test_registered_env_has_max_episode_steps_100():
    assert "avq/GridMaze-v0" in gym.registry
    assert gym.spec("avq/GridMaze-v0").max_episode_steps == 100
    env = gym.make("avq/GridMaze-v0")
    assert env.spec.max_episode_steps == 100


def test_registered_env_truncates_at_step_100():
    # S at (0, 0): moving West bumps into the grid's edge for ever. (Two rows, so
    # that no observation bound is degenerate, which Gymnasium warns about.)
    env = gym.make("avq/GridMaze-v0", layout=["S.", ".G"], start="fixed")
    obs, info = env.reset(seed=0)
    assert pos(obs) == (0.0, 0.0)
    for t in range(1, 100):
        obs, reward, terminated, truncated, info = env.step(WEST)
        assert (reward, terminated, truncated) == (-10.0, False, False), t
        assert info["collision"] is True
        assert pos(obs) == (0.0, 0.0)
    obs, reward, terminated, truncated, info = env.step(WEST)
    assert (reward, terminated, truncated) == (-10.0, False, True)
    # A new episode starts a new count.
    env.reset()
    _, _, _, truncated, _ = env.step(WEST)
    assert truncated is False


# -- 3. The reference layout ----------------------------------------------------------


def test_lau2002_layout_matches_spec():
    assert MAPS["lau2002"] == LAU2002
    lay = load_layout("lau2002")
    assert lay.name == "lau2002"
    assert (lay.width, lay.height) == (14, 12)
    assert lay.n_states == 98
    assert len(lay.free_positions(include_goal=True)) == 98
    assert len(lay.free_positions()) == 97
    assert lay.goal == (12, 7)
    assert lay.start == (1, 1)
    assert lay.distances[7, 12] == 0
    assert lay.distances[1, 1] == 17  # Manhattan distance, nothing in the way
    assert lay.distances[8, 12] == 1
    assert lay.distances[7, 10] == 8  # the pocket left of the goal: up, over, down
    assert lay.distances[0, 0] == -1


def test_lau2002_observation_space():
    env = GridMaze()  # lau2002 is the default
    assert env.layout.name == "lau2002"
    space = env.observation_space
    assert isinstance(space, gym.spaces.Box)
    assert space.dtype == np.float32
    assert space.shape == (2,)
    np.testing.assert_array_equal(space.low, [0.0, 0.0])
    np.testing.assert_array_equal(space.high, [13.0, 11.0])
    assert env.action_space == gym.spaces.Discrete(4)


def test_small_layout_observation_space():
    env = GridMaze(SMALL)
    np.testing.assert_array_equal(env.observation_space.low, [0.0, 0.0])
    np.testing.assert_array_equal(env.observation_space.high, [4.0, 2.0])


# -- 4. Dynamics ------------------------------------------------------------------


def test_action_constants():
    assert (NORTH, EAST, SOUTH, WEST) == (0, 1, 2, 3)


@pytest.mark.parametrize(
    "start, action, end, reward, terminated, collision",
    [
        # plain moves: -1
        ((1, 1), NORTH, (1, 0), -1.0, False, False),
        ((1, 1), SOUTH, (1, 2), -1.0, False, False),
        ((1, 1), WEST, (0, 1), -1.0, False, False),
        ((1, 2), EAST, (2, 2), -1.0, False, False),
        ((3, 2), NORTH, (3, 1), -1.0, False, False),
        # into a wall: -10, robot stays
        ((1, 1), EAST, (1, 1), -10.0, False, True),
        ((3, 1), WEST, (3, 1), -10.0, False, True),
        ((2, 2), NORTH, (2, 2), -10.0, False, True),
        # off the grid's edge: -10, robot stays
        ((0, 0), NORTH, (0, 0), -10.0, False, True),
        ((0, 0), WEST, (0, 0), -10.0, False, True),
        ((4, 2), SOUTH, (4, 2), -10.0, False, True),
        ((4, 2), EAST, (4, 2), -10.0, False, True),
        ((4, 0), EAST, (4, 0), -10.0, False, True),
        # onto the goal: +10, episode ends
        ((3, 1), EAST, (4, 1), 10.0, True, False),
        ((4, 0), SOUTH, (4, 1), 10.0, True, False),
        ((4, 2), NORTH, (4, 1), 10.0, True, False),
    ],
)
def test_single_step(start, action, end, reward, terminated, collision):
    env = GridMaze(SMALL)
    obs, info = env.reset(seed=0, options={"start": start})
    assert pos(obs) == start
    assert info == {"collision": False, "distance": int(SMALL_DIST[start[1], start[0]])}
    obs, r, term, trunc, info = env.step(action)
    assert obs.dtype == np.float32
    assert obs.shape == (2,)
    assert pos(obs) == end
    assert env.position == end
    assert r == reward
    assert isinstance(r, float)
    assert term is terminated
    assert trunc is False
    assert info["collision"] is collision
    assert info["distance"] == SMALL_DIST[end[1], end[0]]


def test_walk_to_goal_by_hand():
    env = GridMaze(SMALL)
    env.reset(options={"start": (1, 1)})
    # (action, position after, reward, collision, distance after)
    script = [
        (NORTH, (1, 0), -1.0, False, 6),
        (EAST, (1, 0), -10.0, True, 6),  # wall at (2, 0)
        (NORTH, (1, 0), -10.0, True, 6),  # top edge
        (WEST, (0, 0), -1.0, False, 7),
        (WEST, (0, 0), -10.0, True, 7),  # left edge
        (SOUTH, (0, 1), -1.0, False, 6),
        (SOUTH, (0, 2), -1.0, False, 5),
        (SOUTH, (0, 2), -10.0, True, 5),  # bottom edge
        (EAST, (1, 2), -1.0, False, 4),
        (EAST, (2, 2), -1.0, False, 3),
        (EAST, (3, 2), -1.0, False, 2),
        (EAST, (4, 2), -1.0, False, 1),
        (EAST, (4, 2), -10.0, True, 1),  # right edge
    ]
    total = 0.0
    for action, where, reward, collision, distance in script:
        obs, r, term, trunc, info = env.step(action)
        assert (pos(obs), r, term, trunc) == (where, reward, False, False)
        assert info == {"collision": collision, "distance": distance}
        total += r
    obs, r, term, trunc, info = env.step(NORTH)
    assert (pos(obs), r, term, trunc) == ((4, 1), 10.0, True, False)
    assert info == {"collision": False, "distance": 0}
    total += r
    assert total == 8 * -1.0 + 5 * -10.0 + 10.0


def test_info_distance_is_bfs_distance_along_a_random_walk():
    env = GridMaze("lau2002")
    obs, info = env.reset(seed=3)
    rng = np.random.default_rng(3)
    dist = env.layout.distances
    for _ in range(300):
        x, y = (int(v) for v in obs)
        assert info["distance"] == dist[y, x]
        obs, r, term, _, info = env.step(int(rng.integers(4)))
        if term:
            assert info["distance"] == 0
            obs, info = env.reset()


# -- 5. Starts --------------------------------------------------------------------


def test_reset_options_start_puts_robot_there():
    env = GridMaze("lau2002", start="fixed")
    for start in [(3, 2), (12, 10), (10, 7)]:
        obs, info = env.reset(options={"start": start})
        assert pos(obs) == start
        assert env.position == start
        assert info == {"collision": False, "distance": int(env.layout.distances[start[1], start[0]])}
    obs, _ = env.reset(options={"start": np.array([4, 9])})
    assert pos(obs) == (4, 9)


@pytest.mark.parametrize("start", [(2, 0), (2, 1)])
def test_reset_start_on_wall_raises(start):
    env = GridMaze(SMALL)
    with pytest.raises(ValueError, match=rf"\({start[0]}, {start[1]}\).*wall"):
        env.reset(options={"start": start})


@pytest.mark.parametrize("start", [(5, 0), (-1, 0), (0, 3), (0, -1), (7, 9)])
def test_reset_start_outside_raises(start):
    env = GridMaze(SMALL)
    with pytest.raises(ValueError, match=rf"\({start[0]}, {start[1]}\).*outside"):
        env.reset(options={"start": start})


@pytest.mark.parametrize("start", [(1,), (1, 2, 3), "ab", 5])
def test_reset_start_not_a_pair_raises(start):
    env = GridMaze(SMALL)
    with pytest.raises(ValueError, match="pair"):
        env.reset(options={"start": start})


def test_fixed_start_uses_S():
    env = GridMaze("lau2002", start="fixed")
    for seed in range(5):
        obs, info = env.reset(seed=seed)
        assert pos(obs) == (1, 1)
        assert info == {"collision": False, "distance": 17}
    env = GridMaze(SMALL, start="fixed")
    obs, info = env.reset()
    assert pos(obs) == (0, 0)
    assert info["distance"] == 7


def test_random_start_covers_all_free_non_goal_positions():
    env = GridMaze("lau2002")  # start="random" is the default
    expected = {(x, y) for y, row in enumerate(LAU2002) for x, ch in enumerate(row) if ch in ".S"}
    assert len(expected) == 97
    env.reset(seed=0)
    seen = set()
    for _ in range(3000):
        obs, _ = env.reset()
        x, y = pos(obs)
        assert x == int(x) and y == int(y)
        seen.add((int(x), int(y)))
    assert (12, 7) not in seen
    assert seen == expected


def test_random_start_is_uniform():
    # corridor: free non-goal positions are (1, 1) .. (4, 1); goal at (5, 1).
    env = GridMaze("corridor")
    env.reset(seed=1)
    n = 8000
    counts = Counter(pos(env.reset()[0]) for _ in range(n))
    assert set(counts) == {(1.0, 1.0), (2.0, 1.0), (3.0, 1.0), (4.0, 1.0)}
    # Expected 2000 each, standard deviation about 39.
    for c in counts.values():
        assert 1800 < c < 2200, counts


def test_random_start_reproducible_with_seed():
    def starts(seed: int) -> list[tuple[float, float]]:
        env = GridMaze("lau2002")
        out = [pos(env.reset(seed=seed)[0])]
        out += [pos(env.reset()[0]) for _ in range(40)]
        return out

    assert starts(123) == starts(123)
    assert starts(123) != starts(124)
    # Re-seeding the same env restarts the same sequence.
    env = GridMaze("lau2002")
    first = [pos(env.reset(seed=7)[0])] + [pos(env.reset()[0]) for _ in range(10)]
    again = [pos(env.reset(seed=7)[0])] + [pos(env.reset()[0]) for _ in range(10)]
    assert first == again


# -- 6. Layout errors and layout files ----------------------------------------------------


@pytest.mark.parametrize("rows", [[], [""], ["", "  "]])
def test_empty_layout_raises(rows):
    with pytest.raises(ValueError, match="empty"):
        parse_layout(rows)
    with pytest.raises(ValueError, match="empty"):
        GridMaze(rows)


def test_ragged_rows_raise_naming_the_row():
    with pytest.raises(ValueError, match=r"row 2 has 2 characters but row 0 has 3"):
        GridMaze(["S..", "...", "G.", "..."])


def test_unknown_character_raises_naming_char_and_position():
    with pytest.raises(ValueError, match=r"unknown character 'X' at x=3, y=1"):
        GridMaze(["S...", "...X", "...G"])


def test_no_goal_raises():
    with pytest.raises(ValueError, match="no goal"):
        GridMaze(["S...", "...."])


def test_several_goals_raise():
    with pytest.raises(ValueError, match=r"2 goals at \[\(0, 0\), \(2, 1\)\]"):
        GridMaze(["G..", "S.G"])


def test_several_starts_raise():
    with pytest.raises(ValueError, match=r"2 starts"):
        GridMaze(["S.S", "..G"])


def test_fixed_start_without_S_raises():
    GridMaze([".G"])  # fine with start="random"
    with pytest.raises(ValueError, match=r"start='fixed' needs an 'S'"):
        GridMaze([".G"], start="fixed")


def test_unreachable_free_positions_raise_naming_one():
    # (0, 0) is walled off from the goal at (2, 1).
    with pytest.raises(ValueError, match=r"cannot reach the goal: \(0, 0\)"):
        GridMaze(["S#.", "##G"])
    # More than five cut-off positions: five are shown, the rest counted.
    with pytest.raises(ValueError, match=r"\(0, 0\).* and 2 more"):
        GridMaze(["....#G", "...##."])


def test_bad_start_and_render_mode_arguments_raise():
    with pytest.raises(ValueError, match="start"):
        GridMaze(SMALL, start="middle")
    with pytest.raises(ValueError, match="render_mode"):
        GridMaze(SMALL, render_mode="human")


def test_unknown_preset_raises():
    with pytest.raises(ValueError, match=r"'no_such_maze' is neither a preset"):
        GridMaze("no_such_maze")


def test_missing_file_raises(tmp_path):
    missing = tmp_path / "missing.txt"
    with pytest.raises(ValueError, match="missing.txt"):
        GridMaze(missing)
    with pytest.raises(ValueError, match="missing.txt"):
        GridMaze(str(missing))


def test_non_layout_argument_raises():
    with pytest.raises(ValueError, match="int"):
        load_layout(5)


def test_layout_from_text_file(tmp_path):
    path = tmp_path / "maze.txt"
    path.write_text("\n".join(LAU2002) + "\n", encoding="utf-8")
    for spec in (path, str(path)):
        env = GridMaze(spec, start="fixed")
        assert env.layout.name == str(path)
        assert env.layout.n_states == 98
        assert env.layout.goal == (12, 7)
        obs, _ = env.reset()
        assert pos(obs) == (1, 1)
        np.testing.assert_array_equal(env.layout.distances, load_layout("lau2002").distances)
    # Windows line endings, and via the registered env.
    path2 = tmp_path / "small.txt"
    path2.write_bytes(("\r\n".join(SMALL) + "\r\n").encode())
    env = gym.make("avq/GridMaze-v0", layout=str(path2))
    np.testing.assert_array_equal(env.unwrapped.layout.distances, SMALL_DIST)


def test_layout_file_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("S.?\n..G\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"bad\.txt.*unknown character '\?' at x=2, y=0"):
        GridMaze(bad)
    empty = tmp_path / "empty.txt"
    empty.write_text("", encoding="utf-8")
    with pytest.raises(ValueError, match=r"empty\.txt.*empty"):
        GridMaze(empty)


def test_multiline_string_layout():
    lay = load_layout("\n".join(SMALL))
    assert lay.rows == tuple(SMALL)
    np.testing.assert_array_equal(lay.distances, SMALL_DIST)


# -- 7. BFS distances ---------------------------------------------------------------


def test_distances_by_hand():
    lay = parse_layout(SMALL)
    assert lay.goal == (4, 1)
    assert lay.start == (0, 0)
    assert lay.n_states == 13
    np.testing.assert_array_equal(lay.walls, SMALL_DIST == -1)
    np.testing.assert_array_equal(lay.distances, SMALL_DIST)


def test_distances_by_hand_with_detour():
    # The wall forces a detour: (0, 0) is 2 columns from the goal but 6 steps away.
    rows = [
        ".#G",
        ".#.",
        "...",
    ]
    expected = np.array(
        [
            [6, -1, 0],
            [5, -1, 1],
            [4, 3, 2],
        ]
    )
    np.testing.assert_array_equal(parse_layout(rows).distances, expected)


def test_free_positions():
    lay = parse_layout(SMALL)
    free = lay.free_positions()
    assert free.shape == (12, 2)
    assert [tuple(p) for p in free[:4]] == [(0, 0), (1, 0), (3, 0), (4, 0)]
    assert (4, 1) not in {tuple(p) for p in free}
    assert (4, 1) in {tuple(p) for p in lay.free_positions(include_goal=True)}
    assert lay.is_free(0, 0) and not lay.is_free(2, 0) and not lay.is_free(5, 0)
    assert not lay.is_free(-1, 0)


# -- 8. Rendering ---------------------------------------------------------------------


def test_render_ansi_marks_robot():
    env = GridMaze(SMALL, render_mode="ansi")
    env.reset(options={"start": (1, 1)})
    text = env.render()
    assert isinstance(text, str)
    assert text == "..#..\n.R#.G\n.....\n"
    env.step(SOUTH)
    text = env.render()
    assert text == "..#..\n..#.G\n.R...\n"
    lines = text.splitlines()
    assert lines[2][1] == "R"
    assert text.count("R") == 1


def test_render_ansi_lau2002_robot_position():
    env = GridMaze(render_mode="ansi")
    env.reset(options={"start": (6, 9)})
    lines = env.render().splitlines()
    assert len(lines) == 12 and all(len(line) == 14 for line in lines)
    assert lines[9][6] == "R"
    assert sum(line.count("R") for line in lines) == 1
    assert lines[7][12] == "G"


def test_render_rgb_array():
    env = GridMaze(SMALL, render_mode="rgb_array")
    env.reset(options={"start": (1, 1)})
    img = env.render()
    assert isinstance(img, np.ndarray)
    assert img.dtype == np.uint8
    assert img.shape == (3 * 16, 5 * 16, 3)
    robot = np.array([200, 50, 50])
    # Centre of the robot's cell is robot-coloured, and robot colour appears nowhere else.
    np.testing.assert_array_equal(img[1 * 16 + 8, 1 * 16 + 8], robot)
    ys, xs = np.nonzero((img == robot).all(axis=2))
    assert len(ys) > 0
    assert ys.min() >= 16 and ys.max() < 32 and xs.min() >= 16 and xs.max() < 32
    np.testing.assert_array_equal(img[0 * 16 + 8, 2 * 16 + 8], [40, 40, 40])  # wall (2, 0)
    np.testing.assert_array_equal(img[1 * 16 + 8, 4 * 16 + 8], [60, 170, 75])  # goal (4, 1)
    np.testing.assert_array_equal(img[2 * 16 + 8, 0 * 16 + 8], [235, 235, 235])  # free (0, 2)


def test_render_rgb_array_lau2002_shape():
    env = GridMaze(render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (12 * 16, 14 * 16, 3)
    assert img.dtype == np.uint8


def test_render_without_mode_returns_none():
    env = GridMaze(SMALL)
    env.reset(seed=0)
    assert env.render() is None


# -- 9. Invalid actions ---------------------------------------------------------------


@pytest.mark.parametrize("action", [4, -1, 1.5, 100, "1", None, np.array([1])])
def test_invalid_actions_raise(action):
    env = GridMaze(SMALL)
    env.reset(options={"start": (1, 1)})
    with pytest.raises(ValueError, match="action"):
        env.step(action)
    assert env.position == (1, 1)


@pytest.mark.parametrize("action", [np.int64(2), np.int32(2), np.array(2)])
def test_numpy_integer_actions_accepted(action):
    env = GridMaze(SMALL)
    env.reset(options={"start": (1, 1)})
    obs, r, *_ = env.step(action)
    assert pos(obs) == (1, 2)
    assert r == -1.0


# -- slip: a stochastic maze ------------------------------------------------------------------------


def test_slip_is_a_probability_and_zero_draws_nothing():
    for bad in (-0.1, 1.0, 1.5, True, "0.1", None):
        with pytest.raises(ValueError, match="slip must be a probability in \\[0, 1\\)"):
            GridMaze(slip=bad)
    env = GridMaze(layout="open5")
    env.reset(seed=3)
    state = env.np_random.bit_generator.state
    for a in (0, 1, 2, 3) * 5:
        env.step(a)
    assert env.np_random.bit_generator.state == state  # deterministic moves draw nothing


def test_a_slip_goes_to_either_side_never_backwards_as_often_as_asked():
    # From the centre of the open 5 x 5 maze, ask for East 6,000 times with slip 0.3: the move goes East
    # with probability 0.7, North and South with 0.15 each, West never.
    env = GridMaze(layout="open5", slip=0.3)
    env.reset(seed=0)
    moves = {(1, 0): 0, (0, -1): 0, (0, 1): 0, (-1, 0): 0}
    for _ in range(6000):
        env.reset(options={"start": (2, 2)})
        obs, _, _, _, _ = env.step(EAST)
        moves[(int(obs[0]) - 2, int(obs[1]) - 2)] += 1
    assert moves[(-1, 0)] == 0
    assert abs(moves[(1, 0)] / 6000 - 0.7) < 0.03
    assert abs(moves[(0, -1)] / 6000 - 0.15) < 0.02 and abs(moves[(0, 1)] / 6000 - 0.15) < 0.02


def test_the_slip_rule_draws_as_documented():
    # u = random() < slip slips; then integers(0, 2) picks a + 1 (0) or a + 3 (1), modulo 4.
    from avq.envs.grid_maze import slipped

    rng, twin = np.random.default_rng(5), np.random.default_rng(5)
    for k in range(200):
        a = k % 4
        want = (a + 1 + 2 * int(twin.integers(0, 2))) % 4 if twin.random() < 0.4 else a
        assert slipped(rng, a, 0.4) == want  # compiled
    assert rng.bit_generator.state == twin.bit_generator.state
    assert slipped.py_func(rng, 2, 0.4) == ((2 + 1 + 2 * int(twin.integers(0, 2))) % 4 if twin.random() < 0.4 else 2)


@pytest.mark.parametrize("name", ["avq-paper", "avq-maze", "avq", "tabular"])
def test_fused_and_generic_training_on_a_slippery_maze_are_identical(name):
    runs = []
    for fused in (True, False):
        agent = avq.make_agent(name, gym.make("avq/GridMaze-v0", slip=0.1), seed=4, fused=fused)
        runs.append(agent.learn(total_episodes=120).learn(total_timesteps=333))
        assert (agent._fused_runner() is not None) == fused
    a, b = runs
    assert np.array_equal(a.q_, b.q_)
    for key in ("steps", "return", "n_cells"):
        assert np.array_equal(a.episode_history()[key], b.episode_history()[key])
