"""Tests for the continuous robot maze with 16 sonars (SPEC §6), numbers worked out by hand."""

from __future__ import annotations

import math
import time
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import avq  # registers the environments
from avq.envs import RobotMaze, register_envs
from avq.envs.robot_geometry import sonar_directions
from avq.envs.robot_maze import EAST, NORTH, SOUTH, WEST

# A small hand-made layout: W = 4, H = 3, so the maze is [-0.5, 3.5] x [-0.5, 2.5].
# The wall square is (1, 1) = [0.5, 1.5] x [0.5, 1.5]; the goal square is
# (3, 2) = [2.5, 3.5] x [1.5, 2.5].
#
#        x: 0 1 2 3
#   y = 0:  . . . .
#   y = 1:  . # . .
#   y = 2:  . . . G
SMALL = ["....", ".#..", "...G"]
# GridMaze's shortest-path steps to the goal on SMALL, by hand; -1 on the wall.
SMALL_DIST = np.array([[5, 4, 3, 2], [4, -1, 2, 1], [3, 2, 1, 0]])

CORRIDOR = ["#######", "#S...G#", "#######"]  # walls at y <= 0.5 and y >= 1.5

R2 = math.sqrt(2.0)
BEAM_N, BEAM_E, BEAM_S, BEAM_W = 0, 4, 8, 12
BEAM_NE, BEAM_SW, BEAM_NW = 2, 10, 14
BEAM_COLOUR = (240, 170, 20)


def pos(obs: np.ndarray) -> tuple[float, float]:
    return float(obs[0]), float(obs[1])


def at(start: tuple[float, float], **kwargs) -> tuple[RobotMaze, dict]:
    """A RobotMaze on SMALL (unless given) with the robot placed at ``start``."""
    kwargs.setdefault("layout", SMALL)
    env = RobotMaze(**kwargs)
    _, info = env.reset(seed=0, options={"start": start})
    return env, info


# -- 1. Gymnasium's env checker and registration --------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [
        {},
        {"observe_sonar": True},
        {"render_mode": "ansi"},
        {"render_mode": "rgb_array"},
        {"render_mode": "rgb_array", "observe_sonar": True, "sonar_noise": 0.3},
        {"render_mode": "ansi", "observe_sonar": True, "start": "fixed"},
        {"layout": SMALL, "move": 0.5, "radius": 0.3},
    ],
    ids=["default", "sonar", "ansi", "rgb_array", "rgb-sonar-noise", "ansi-sonar-fixed", "small"],
)
def test_check_env_passes_without_warnings(kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make("avq/RobotMaze-v0", **kwargs)
        assert isinstance(env.unwrapped, RobotMaze)
        check_env(env.unwrapped)
        env.close()


def test_registered_without_max_episode_steps_and_idempotent():
    register_envs()
    register_envs()
    assert gym.spec("avq/RobotMaze-v0").max_episode_steps is None
    env = gym.make("avq/RobotMaze-v0")
    assert env.unwrapped.max_steps == 400
    assert "RobotMaze" in avq.envs.__all__


def test_spaces():
    env = RobotMaze(SMALL)
    assert env.action_space == gym.spaces.Discrete(4)
    space = env.observation_space
    assert (space.shape, space.dtype) == ((2,), np.float32)
    np.testing.assert_array_equal(space.low, [-0.5, -0.5])
    np.testing.assert_array_equal(space.high, [3.5, 2.5])
    space = RobotMaze(SMALL, observe_sonar=True, sonar_range=3.0).observation_space
    assert space.shape == (18,)
    np.testing.assert_array_equal(space.low, [-0.5, -0.5] + [0.0] * 16)
    np.testing.assert_array_equal(space.high, [3.5, 2.5] + [3.0] * 16)
    # lau2002 (the default) is 14 x 12.
    np.testing.assert_array_equal(RobotMaze().observation_space.high, [13.5, 11.5])


# -- 2. Moves, collisions and the goal --------------------------------------------------


def test_free_move_costs_one_and_moves_exactly():
    env, _ = at((0.0, 0.0))  # radius 0.2, move 0.25
    obs, r, term, trunc, info = env.step(EAST)
    assert pos(obs) == (0.25, 0.0) == env.position
    assert (r, term, trunc, info["collision"]) == (-1.0, False, False, False)
    assert isinstance(r, float)
    obs, *_ = env.step(SOUTH)
    assert pos(obs) == (0.25, 0.25)
    obs, *_ = env.step(WEST)
    assert pos(obs) == (0.0, 0.25)
    obs, *_ = env.step(NORTH)
    assert pos(obs) == (0.0, 0.0)


def test_collision_with_a_wall_robot_stays():
    # From (2, 1), West: to 1.75 (0.25 from the wall's face x = 1.5, more than the
    # radius 0.2), then to 1.5, where the disc would overlap the wall.
    env, _ = at((2.0, 1.0))
    obs, r, term, _, info = env.step(WEST)
    assert (pos(obs), r, info["collision"]) == ((1.75, 1.0), -1.0, False)
    obs, r, term, trunc, info = env.step(WEST)
    assert pos(obs) == (1.75, 1.0) == env.position  # stays, does not stop at contact
    assert (r, term, trunc, info["collision"]) == (-10.0, False, False, True)
    obs, r, *_ = env.step(WEST)  # and again
    assert (pos(obs), r) == ((1.75, 1.0), -10.0)


@pytest.mark.parametrize(
    "start, action",
    [
        ((0.0, 0.0), NORTH),  # to y = -0.5: y - r = -0.7 < -0.5
        ((0.0, 0.0), WEST),
        ((3.25, 0.0), EAST),  # to x = 3.75: x + r = 3.95 > 3.5
        ((1.0, 2.25), SOUTH),  # to y = 2.75: y + r = 2.95 > 2.5
    ],
)
def test_collision_with_the_maze_edge_robot_stays(start, action):
    env, _ = at(start, move=0.5)
    obs, r, term, trunc, info = env.step(action)
    assert pos(obs) == start
    assert (r, term, trunc, info["collision"]) == (-10.0, False, False, True)


def test_touching_exactly_at_radius_is_not_a_collision():
    # radius 0.25, move 0.25: all values exact in binary.
    env, _ = at((2.0, 1.0), radius=0.25)
    obs, r, _, _, info = env.step(WEST)  # x = 1.75: 0.25 from the wall's face, touching
    assert (pos(obs), r, info["collision"]) == ((1.75, 1.0), -1.0, False)
    assert info["sonar"][BEAM_W] == 0.0  # the robot's surface is on the wall
    obs, r, _, _, info = env.step(WEST)  # x = 1.5 would overlap
    assert (pos(obs), r, info["collision"]) == ((1.75, 1.0), -10.0, True)
    # The maze's edge: x = -0.25 touches x = -0.5.
    env, _ = at((0.0, 0.0), radius=0.25)
    obs, r, _, _, info = env.step(WEST)
    assert (pos(obs), r, info["collision"]) == ((-0.25, 0.0), -1.0, False)
    obs, r, _, _, info = env.step(WEST)
    assert (pos(obs), r, info["collision"]) == ((-0.25, 0.0), -10.0, True)


def test_touching_a_wall_corner_exactly_at_radius():
    # The wall's corner (1.5, 0.5) is (3/16, 4/16) from (1.6875, 0.25): distance
    # 5/16 = 0.3125 = the radius.
    env, _ = at((1.75, 0.25), radius=0.3125, move=0.0625)
    obs, r, _, _, info = env.step(WEST)
    assert (pos(obs), r, info["collision"]) == ((1.6875, 0.25), -1.0, False)
    obs, r, _, _, info = env.step(WEST)  # x = 1.625: (1/8, 1/4) from the corner, 0.28 < 0.3125
    assert (pos(obs), r, info["collision"]) == ((1.6875, 0.25), -10.0, True)


@pytest.mark.parametrize(
    "start, actions, end",
    [
        ((3.0, 1.0), [SOUTH, SOUTH], (3.0, 1.5)),  # onto the goal's top edge
        ((2.0, 2.0), [EAST, EAST], (2.5, 2.0)),  # onto its left edge
        ((3.0, 0.375), [SOUTH] * 5, (3.0, 1.625)),  # into it (1.375 is still outside)
    ],
)
def test_reaching_the_goal_square_terminates_with_plus_ten(start, actions, end):
    env, _ = at(start)
    for a in actions[:-1]:
        _, r, term, _, _ = env.step(a)
        assert (r, term) == (-1.0, False)
    obs, r, term, trunc, info = env.step(actions[-1])
    assert pos(obs) == end
    assert (r, term, trunc, info["collision"], info["distance"]) == (10.0, True, False, False, 0)


def test_info_distance_is_the_grid_distance_of_the_square_containing_the_centre():
    env, info = at((2.0, 1.0))
    assert set(info) == {"collision", "distance", "sonar"}
    assert (info["collision"], info["distance"]) == (False, 2)
    for where, expected in [((0.2, 0.3), 5), ((0.0, 1.9), 3), ((3.2, 0.7), 1), ((2.4, 1.4), 2)]:
        _, info = env.reset(options={"start": where})
        x, y = where
        assert info["distance"] == expected == SMALL_DIST[round(y), round(x)]
    # On the boundary between (1, 2) and (2, 2) the square East of it counts.
    _, info = env.reset(options={"start": (1.5, 2.0)})
    assert info["distance"] == 1


def test_bad_action_raises():
    env, _ = at((0.0, 0.0))
    for action in (4, -1, 1.5, True, "N"):
        with pytest.raises(ValueError, match="action"):
            env.step(action)
    env.step(np.int64(1))
    env.step(np.array(2))


# -- 3. Sonar ------------------------------------------------------------------------------


def test_beam_directions_are_compass_bearings():
    d = sonar_directions()
    assert d.shape == (16, 2)
    np.testing.assert_array_equal(d[[BEAM_N, BEAM_E, BEAM_S, BEAM_W]], [[0, -1], [1, 0], [0, 1], [-1, 0]])
    h = math.sqrt(0.5)
    np.testing.assert_array_equal(d[BEAM_NE], [h, -h])
    np.testing.assert_array_equal(d[BEAM_NW], [-h, -h])
    theta = np.deg2rad(22.5 * np.arange(16))
    np.testing.assert_allclose(d, np.stack([np.sin(theta), -np.cos(theta)], axis=1), atol=1e-15)


def test_sonar_ranges_by_hand():
    # Robot at (2, 0.75), radius 0.2, in SMALL.
    _, info = at((2.0, 0.75))
    s = info["sonar"]
    assert s.dtype == np.float32 and s.shape == (16,)
    expected = {
        BEAM_N: 1.25 - 0.2,  # to the top edge y = -0.5
        BEAM_E: 1.5 - 0.2,  # to the right edge x = 3.5
        BEAM_S: 1.75 - 0.2,  # to the bottom edge y = 2.5 (column 2 is free)
        BEAM_W: 0.5 - 0.2,  # to the wall's face x = 1.5
        # South-West: (2 - s, 0.75 + s) meets x = 1.5 at s = 0.5, y = 1.25: the wall's face.
        BEAM_SW: 0.5 * R2 - 0.2,
        # North-West: (2 - s, 0.75 - s) passes above the wall's corner (x = 1.5 at y = 0.25)
        # and meets the top edge y = -0.5 at s = 1.25 (x = 0.75, a free square).
        BEAM_NW: 1.25 * R2 - 0.2,
        # 22.5 degrees: meets the top edge after 1.25 / cos(22.5 deg), at x = 2.52 (free).
        1: 1.25 / math.cos(math.pi / 8) - 0.2,
    }
    for k, value in expected.items():
        assert s[k] == pytest.approx(value, abs=1e-6), k


def test_sonar_beams_grazing_a_wall_edge_or_corner_stop_there():
    # Running along the wall's right edge x = 1.5, or its left edge x = 0.5: 0.5 to the wall.
    for x in (1.5, 0.5):
        _, info = at((x, 2.0))
        assert info["sonar"][BEAM_N] == pytest.approx(0.3, abs=1e-6)
    _, info = at((1.75, 2.0))  # a quarter to the right: free up to the top edge
    assert info["sonar"][BEAM_N] == pytest.approx(2.5 - 0.2, abs=1e-6)
    # From (2, 1) the North-West beam passes exactly through the wall's corner (1.5, 0.5).
    _, info = at((2.0, 1.0))
    assert info["sonar"][BEAM_NW] == pytest.approx(0.5 * R2 - 0.2, abs=1e-6)
    # ... and the North-East beam through the maze's corner (3.5, -0.5).
    assert info["sonar"][BEAM_NE] == pytest.approx(1.5 * R2 - 0.2, abs=1e-6)


def test_sonar_is_clipped_to_its_range():
    _, info = at((2.0, 0.75), sonar_range=1.0)
    s = info["sonar"]
    assert s[BEAM_N] == s[BEAM_E] == s[BEAM_S] == 1.0
    assert s[BEAM_W] == pytest.approx(0.3, abs=1e-6)
    assert s.max() == 1.0


def _reference_sonar(walls: np.ndarray, x: float, y: float, radius: float, max_range: float) -> np.ndarray:
    """Slab test of each beam against every closed wall square and the maze's edges."""
    h, w = walls.shape
    theta = np.deg2rad(22.5 * np.arange(16))
    out = np.empty(16)
    for k, (dx, dy) in enumerate(zip(np.sin(theta), -np.cos(theta))):
        dx = 0.0 if abs(dx) < 1e-12 else dx
        dy = 0.0 if abs(dy) < 1e-12 else dy
        exits = [
            (w - 0.5 - x) / dx if dx > 0 else (-0.5 - x) / dx if dx < 0 else np.inf,
            (h - 0.5 - y) / dy if dy > 0 else (-0.5 - y) / dy if dy < 0 else np.inf,
        ]
        best = min(exits)
        for j, i in zip(*np.nonzero(walls)):
            lo, hi = -np.inf, np.inf
            for p, d, c in ((x, dx, i), (y, dy, j)):
                if d == 0:
                    if not c - 0.5 <= p <= c + 0.5:
                        lo, hi = np.inf, -np.inf
                else:
                    t1, t2 = (c - 0.5 - p) / d, (c + 0.5 - p) / d
                    lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
            if lo <= hi and hi >= 0:
                best = min(best, max(lo, 0.0))
        out[k] = min(max(best - radius, 0.0), max_range)
    return out


def test_sonar_matches_a_slab_test_at_random_positions():
    env = RobotMaze("lau2002", sonar_range=6.0)
    env.reset(seed=5)
    walls = env.layout.walls
    for _ in range(60):
        _, info = env.reset()
        expected = _reference_sonar(walls, env.position[0], env.position[1], 0.2, 6.0)
        np.testing.assert_allclose(info["sonar"], expected, atol=1e-5)


def test_sonar_noise_reproducible_with_a_seed_and_clipped():
    def readings(seed: int, noise: float) -> list[np.ndarray]:
        env = RobotMaze(SMALL, sonar_noise=noise, sonar_range=2.0)
        out = [env.reset(seed=seed, options={"start": (2.0, 0.75)})[1]["sonar"]]
        out += [env.step(a)[4]["sonar"] for a in (NORTH, SOUTH, EAST)]
        return out

    clean = readings(0, 0.0)
    a, b, c = readings(1, 0.1), readings(1, 0.1), readings(2, 0.1)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a[0], c[0])
    assert not np.array_equal(a[0], clean[0])
    assert not np.array_equal(a[0], a[2])  # back at (2, 0.75) after N then S: new noise
    np.testing.assert_array_equal(clean[0], clean[2])
    # With std 0.1 the noise stays small where the clean range is inside (0, 2).
    assert np.abs(a[0] - clean[0])[BEAM_W] < 0.6
    # Huge noise: every reading clipped to 0 or 2.
    wild = np.concatenate(readings(3, 1e6))
    assert wild.min() == 0.0 and wild.max() == 2.0
    assert np.all((wild == 0.0) | (wild == 2.0))


def test_observe_sonar_appends_the_ranges_to_the_position():
    env, _ = at((2.0, 0.75), observe_sonar=True)
    obs, _, _, _, info = env.step(EAST)
    assert obs.shape == (18,) and obs.dtype == np.float32
    assert pos(obs) == (2.25, 0.75)
    np.testing.assert_array_equal(obs[2:], info["sonar"])
    assert obs[2 + BEAM_W] == pytest.approx(0.55, abs=1e-6)  # 0.75 to the wall's face
    assert obs[2 + BEAM_E] == pytest.approx(1.05, abs=1e-6)
    assert env.observation_space.contains(obs)


# -- 4. Episode length ---------------------------------------------------------------------


@pytest.mark.parametrize("move, limit", [(0.25, 400), (0.5, 200), (1.0, 100), (0.3, 334)])
def test_step_limit_is_ceil_100_over_move(move, limit):
    assert RobotMaze(SMALL, move=move).max_steps == limit


def test_truncates_after_max_steps_and_counts_again_after_reset():
    # Bumping into the top edge from (0, -0.25) for ever (radius 0.2: y - r = -0.45;
    # a move North would give -0.7).
    env = gym.make("avq/RobotMaze-v0", layout=SMALL)
    env.reset(seed=0, options={"start": (0.0, -0.25)})
    for t in range(1, 400):
        obs, r, term, trunc, info = env.step(NORTH)
        assert (pos(obs), r, term, trunc, info["collision"]) == ((0.0, -0.25), -10.0, False, False, True), t
    _, r, term, trunc, _ = env.step(NORTH)
    assert (r, term, trunc) == (-10.0, False, True)
    env.reset()
    _, _, _, trunc, _ = env.step(NORTH)
    assert trunc is False
    env = RobotMaze(SMALL, max_steps=3)
    env.reset(options={"start": (0.0, 0.0)})
    assert [env.step(EAST)[3] for _ in range(3)] == [False, False, True]


# -- 5. Starts -------------------------------------------------------------------------------


def _min_wall_distance(walls: np.ndarray, x: float, y: float) -> float:
    """Distance from (x, y) to the nearest wall square or the maze's edge (brute force)."""
    h, w = walls.shape
    js, is_ = np.nonzero(walls)
    dx = np.maximum(np.abs(x - is_) - 0.5, 0.0)
    dy = np.maximum(np.abs(y - js) - 0.5, 0.0)
    return min(x + 0.5, w - 0.5 - x, y + 0.5, h - 0.5 - y, float(np.hypot(dx, dy).min()))


def test_random_starts_never_overlap_and_cover_every_square():
    env = RobotMaze("lau2002", radius=0.3)
    walls = env.layout.walls
    env.reset(seed=0)
    squares = set()
    near_edge = 0
    for _ in range(1500):
        obs, info = env.reset()
        x, y = env.position
        assert obs.dtype == np.float32 and pos(obs) == pytest.approx((x, y), abs=1e-6)
        d = _min_wall_distance(walls, x, y)
        assert d >= 0.3 - 1e-9, (x, y)
        near_edge += d < 0.4
        square = (round(x), round(y))
        assert square != env.layout.goal and not walls[square[1], square[0]]
        assert info["collision"] is False
        squares.add(square)
    assert len(squares) == 97
    assert near_edge > 0  # positions are not confined to the squares' middles


def test_random_starts_reproducible_with_seed():
    def starts(seed: int) -> list[tuple[float, float]]:
        env = RobotMaze("lau2002")
        out = [pos(env.reset(seed=seed)[0])]
        return out + [pos(env.reset()[0]) for _ in range(30)]

    assert starts(11) == starts(11)
    assert starts(11) != starts(12)
    assert all(x != round(x) for x, _ in starts(11))  # continuous, not square centres


def test_fixed_start_is_the_centre_of_S():
    env = RobotMaze("lau2002", start="fixed")
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        assert pos(obs) == (1.0, 1.0)
        assert info["distance"] == 17


def test_reset_options_start_any_continuous_position():
    env, info = at((2.3, 0.35))
    assert env.position == (2.3, 0.35)
    assert info["collision"] is False
    env.reset(options={"start": np.array([0.2, 1.9])})
    assert env.position == (0.2, 1.9)


@pytest.mark.parametrize(
    "start, match",
    [
        ((1.0, 1.0), r"\(1.0, 1.0\).*overlap a wall"),  # on the wall
        ((1.65, 1.0), r"\(1.65, 1.0\).*overlap a wall"),  # 0.15 from its face, radius 0.2
        ((1.6, 0.4), r"\(1.6, 0.4\).*overlap a wall"),  # 0.14 from its corner
        ((-0.4, 0.0), r"\(-0.4, 0.0\).*outside the maze"),  # disc crosses the edge
        ((5.0, 1.0), r"\(5.0, 1.0\).*outside the maze"),
        ((3.0, 2.0), r"\(3.0, 2.0\).*goal"),
        ((2.5, 1.5), r"\(2.5, 1.5\).*goal"),  # the goal square's corner
        ((1,), "pair"),
        ("ab", "pair"),
        ((float("nan"), 1.0), "finite"),
    ],
)
def test_bad_start_option_raises_naming_the_position(start, match):
    env = RobotMaze(SMALL)
    with pytest.raises(ValueError, match=match):
        env.reset(options={"start": start})


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"radius": 0.0}, r"radius must be in \(0, 0.5\)"),
        ({"radius": 0.5}, r"radius must be in \(0, 0.5\)"),
        ({"radius": -0.1}, r"radius must be in \(0, 0.5\)"),
        ({"radius": "big"}, "radius must be a number"),
        ({"move": 0.0}, r"move must be in \(0, 1\]"),
        ({"move": 1.5}, r"move must be in \(0, 1\]"),
        ({"sonar_range": 0.0}, "sonar_range must be a finite number > 0"),
        ({"sonar_range": float("inf")}, "sonar_range must be a finite number > 0"),
        ({"sonar_noise": -0.1}, "sonar_noise must be a finite number >= 0"),
        ({"start": "middle"}, "start must be 'random' or 'fixed'"),
        ({"start": "fixed"}, r"start='fixed' needs an 'S'"),  # SMALL has none
        ({"max_steps": 0}, "max_steps must be None or an integer >= 1"),
        ({"max_steps": 2.5}, "max_steps must be None or an integer >= 1"),
        ({"render_mode": "human"}, "render_mode must be one of"),
        ({"layout": "no_such_maze"}, "neither a preset"),
    ],
)
def test_bad_arguments_raise_naming_them(kwargs, match):
    kwargs.setdefault("layout", SMALL)
    with pytest.raises(ValueError, match=match):
        RobotMaze(**kwargs)


# -- 6. Evaluation helpers -------------------------------------------------------------------


def test_start_positions_are_the_free_non_goal_square_centres():
    starts = RobotMaze(SMALL).start_positions()
    assert starts.dtype == np.float64 and starts.shape == (10, 2)
    assert [tuple(p) for p in starts] == [
        (0, 0),
        (1, 0),
        (2, 0),
        (3, 0),
        (0, 1),
        (2, 1),
        (3, 1),
        (0, 2),
        (1, 2),
        (2, 2),
    ]
    assert len(RobotMaze().start_positions()) == 97


@pytest.mark.parametrize(
    "where, steps",
    [
        ((1.0, 1.0), 7),  # x must reach 4.5 (the goal's face): 3.5 / 0.5 = 7 moves
        ((1.25, 1.0), 7),  # 1.25 + 0.5 * 7 = 4.75 >= 4.5 > 4.25
        ((1.5, 1.0), 6),
        ((2.3, 1.1), 5),  # 2.3 + 2.5 = 4.8; y cannot change (1.1 +- 0.5 hits a wall)
        ((4.5, 1.0), 0),  # already on the goal's edge
    ],
)
def test_shortest_steps_in_a_corridor_by_hand(where, steps):
    env = RobotMaze(CORRIDOR, move=0.5)
    assert env.shortest_steps(*where) == steps


@pytest.mark.parametrize("move, steps", [(1.0, 4), (0.5, 7), (0.25, 11)])
def test_shortest_steps_around_a_wall_by_hand(move, steps):
    # From (0, 0) to the goal square [1.5, 2.5] x [-0.5, 0.5] behind the wall (1, 0),
    # radius 0.2: below the wall the centre needs y >= 0.7, and to come up beside it
    # x >= 1.7. move 1: 1 down, 2 East, 1 up = 4 (GridMaze's distance). move 0.5:
    # down to y = 1 (2), East to x = 2 (4), up to 0.5 (1) = 7. move 0.25: down to
    # 0.75 (3), East to 1.75 (7), up to 0.5 (1) = 11, fewer than 4 * 4 - 2 because
    # the disc can hug the wall.
    env = RobotMaze(["S#G", "..."], move=move)
    assert env.shortest_steps(0.0, 0.0) == steps


def test_shortest_steps_unreachable_is_minus_one():
    # A one-square gap at column 2 ([1.5, 2.5]) that a disc of radius 0.45 passes only
    # with its centre in [1.95, 2.05]: never from the lattice x = 0.5 + integer.
    env = RobotMaze(["....", "##.#", "...G"], radius=0.45, move=1.0)
    assert env.shortest_steps(0.5, 0.0) == -1
    assert env.shortest_steps(2.0, 0.0) == 3  # down, down, East
    with pytest.raises(ValueError, match="overlap a wall"):
        env.shortest_steps(1.0, 1.0)


def _bfs_through_step(env: RobotMaze, start: tuple[float, float]) -> int:
    """Least number of env.step calls from ``start`` to termination, by searching with the env itself."""
    frontier, seen, depth = [start], {(round(start[0], 6), round(start[1], 6))}, 0
    while frontier:
        depth += 1
        nxt = []
        for p in frontier:
            for a in range(4):
                env.reset(options={"start": p})
                _, _, term, _, info = env.step(a)
                if term:
                    return depth
                key = (round(env.position[0], 6), round(env.position[1], 6))
                if not info["collision"] and key not in seen:
                    seen.add(key)
                    nxt.append(env.position)
        frontier = nxt
    return -1


def test_shortest_steps_agrees_with_a_search_through_step():
    env = RobotMaze(SMALL, move=0.25, radius=0.3)
    for start in [(0.0, 0.0), (0.0, 2.0), (2.0, 0.25), (1.7, 0.1)]:
        assert env.shortest_steps(*start) == _bfs_through_step(env, start), start


def test_shortest_steps_for_every_start_matches_grid_at_move_one_and_is_fast():
    env = RobotMaze("lau2002", move=1.0)
    dist = env.layout.distances
    for x, y in env.start_positions():
        assert env.shortest_steps(x, y) == dist[int(y), int(x)]
    # move 0.25: one lattice (a ~56 x 48 search) serves every start.
    env = RobotMaze("lau2002")
    t0 = time.perf_counter()
    steps = [env.shortest_steps(x, y) for x, y in env.start_positions()]
    assert time.perf_counter() - t0 < 2.0
    for (x, y), s in zip(env.start_positions(), steps):
        d = dist[int(y), int(x)]
        # GridMaze's path is one way to go (4 moves a square, half a square into the
        # goal); hugging walls can only shorten it, never below the Manhattan distance
        # from the centre to the goal square.
        manhattan = max(abs(x - 12) - 0.5, 0) + max(abs(y - 7) - 0.5, 0)
        assert 4 * manhattan <= s <= 4 * d - 2, (x, y)
    assert steps[0] < 4 * dist[1, 1] - 2  # from S, hugging walls saves a move


# -- 7. Rendering --------------------------------------------------------------------------


def test_rgb_array_shows_walls_goal_robot_and_beams():
    env, _ = at((2.0, 0.75), render_mode="rgb_array")
    img = env.render()
    assert img.shape == (3 * 32, 4 * 32, 3) and img.dtype == np.uint8

    def pixel(x: float, y: float) -> tuple[int, ...]:
        return tuple(int(v) for v in img[int((y + 0.5) * 32), int((x + 0.5) * 32)])

    assert pixel(1.0, 1.0) == (40, 40, 40)  # wall
    assert pixel(3.0, 2.0) == (60, 170, 75)  # goal
    assert pixel(2.0, 0.75) == (200, 50, 50)  # robot
    assert pixel(2.0, 0.25) == BEAM_COLOUR  # on the North beam, 0.3 past the surface
    assert pixel(0.0, 2.0) == (235, 235, 235)  # free, no beam
    assert np.all(img == BEAM_COLOUR, axis=2).sum() > 100


def test_ansi_marks_the_robot_square():
    env, _ = at((2.0, 0.75), render_mode="ansi")
    assert env.render() == "....\n.#R.\n...G\n"
    env = RobotMaze("lau2002", start="fixed", render_mode="ansi")
    env.reset()
    assert env.render().splitlines()[1] == "#R...........#"
    assert RobotMaze(SMALL).render() is None


@pytest.mark.parametrize("name", ["avq", "grid"])
def test_evaluate_maze_walks_in_lockstep_exactly_as_stepping_the_env(name):
    import avq
    from avq.evaluation import evaluate_maze

    agent = avq.make_agent(name, gym.make("avq/RobotMaze-v0"), seed=1).learn(total_episodes=40)
    result = evaluate_maze(agent, gym.make("avq/RobotMaze-v0"))
    base = gym.make("avq/RobotMaze-v0").unwrapped
    for outcome in result["outcomes"]:
        obs, _ = base.reset(options={"start": outcome["start"]})
        steps, success = 0, False
        while steps < base.max_steps and not success:
            obs, _, success, _, _ = base.step(agent.predict(obs)[0])
            steps += 1
        assert (outcome["success"], outcome["steps"]) == (success, steps), outcome["start"]
