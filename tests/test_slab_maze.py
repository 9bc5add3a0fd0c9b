"""Tests for the d-dimensional slab maze, numbers worked out by hand."""

from __future__ import annotations

import math
import warnings
from collections import Counter, deque

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import avq
from avq.envs import SlabMaze
from avq.envs.slab_geometry import regions_reaching_goal

# The unit square with one slab across axis 0 at x = 0.5, open where 0.2 <= y <= 0.4 (the entries on the
# slab's own axis, 0 and 1 here, are ignored). move = 0.1, goal_size = 0.1: the goal is [0.9, 1]^2.
#
#   y = 1  .....|...G
#          .....|....
#   y=0.4  .......... <- the opening
#   y=0.2  ..........
#   y = 0  R....|....
DOOR = [(0, 0.5, (0.0, 0.2), (1.0, 0.4))]
UP_X, DOWN_X, UP_Y, DOWN_Y = 0, 1, 2, 3


def at(start, walls=DOOR, **kwargs) -> SlabMaze:
    """A SlabMaze (2-D, DOOR, unless told) with the point placed at ``start``."""
    kwargs.setdefault("dims", len(start))
    env = SlabMaze(walls=walls, **kwargs)
    env.reset(seed=0, options={"start": start})
    return env


# -- Gymnasium's checker, registration, spaces -------------------------------------------------


@pytest.mark.parametrize(
    "kwargs",
    [{"dims": 2}, {"dims": 3, "slip": 0.2}, {"dims": 8}, {"dims": 8, "walls": 16, "start": "fixed"}, {"walls": DOOR}],
    ids=["d2", "d3-slip", "d8", "d8-16-walls-fixed", "stated"],
)
def test_check_env_passes_without_warnings(kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env = gym.make("avq/SlabMaze-v0", render_mode="ansi", **kwargs)
        assert isinstance(env.unwrapped, SlabMaze)
        check_env(env.unwrapped, skip_render_check=False)


def test_registered_without_max_episode_steps():
    assert gym.spec("avq/SlabMaze-v0").max_episode_steps is None
    assert {"SlabMaze", "IrrelevantDims"} <= set(avq.envs.__all__)


@pytest.mark.parametrize("d", [2, 3, 8])
def test_spaces(d):
    env = SlabMaze(dims=d)
    assert env.action_space == gym.spaces.Discrete(2 * d)
    box = env.observation_space
    assert box.shape == (d,) and box.dtype == np.float32
    assert np.all(box.low == 0.0) and np.all(box.high == 1.0)


@pytest.mark.parametrize(
    ("d", "move", "states"),
    [(2, 0.1, 100), (3, 0.1, 1000), (4, 0.1, 10**4), (6, 0.1, 10**6), (8, 0.1, 10**8), (2, 0.25, 16), (3, 0.3, 64)],
)
def test_full_resolution_states_is_ceil_one_over_move_to_the_d(d, move, states):
    assert SlabMaze(dims=d, move=move, goal_size=max(move, 0.1)).full_resolution_states == states


@pytest.mark.parametrize(("d", "move", "limit"), [(2, 0.1, 200), (3, 0.1, 300), (8, 0.1, 800), (2, 0.25, 80)])
def test_step_limit_is_ceil_10_d_over_move(d, move, limit):
    assert SlabMaze(dims=d, move=move, goal_size=0.25).max_steps == limit


# -- the rules, by hand -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("start", "action"),
    [((0.45, 0.7), UP_X), ((0.55, 0.7), DOWN_X), ((0.4, 0.7), UP_X), ((0.45, 0.1), UP_X), ((0.45, 0.41), UP_X)],
    ids=["across-up", "across-down", "landing-on-the-plane", "below-the-opening", "just-above-it"],
)
def test_crossing_a_slab_outside_its_opening_is_a_collision_and_the_point_stays(start, action):
    env = at(start)
    obs, reward, terminated, truncated, info = env.step(action)
    assert reward == -10.0 and info["collision"] is True and not terminated and not truncated
    np.testing.assert_array_equal(env.position, start)
    np.testing.assert_array_equal(obs, np.float32(start))


@pytest.mark.parametrize(
    ("start", "action", "end"),
    [
        ((0.45, 0.3), UP_X, (0.55, 0.3)),
        ((0.55, 0.3), DOWN_X, (0.45, 0.3)),
        ((0.45, 0.4), UP_X, (0.55, 0.4)),  # the opening is closed: its edge lets the point through
        ((0.45, 0.2), UP_X, (0.55, 0.2)),
        ((0.45, 0.7), UP_Y, (0.45, 0.8)),  # along the slab: no crossing
        ((0.3, 0.7), UP_X, (0.4, 0.7)),
    ],
)
def test_a_move_through_the_opening_or_away_from_slabs_passes_with_minus_one(start, action, end):
    env = at(start)
    _, reward, terminated, _, info = env.step(action)
    assert reward == -1.0 and info["collision"] is False and not terminated
    np.testing.assert_allclose(env.position, end, atol=1e-12)


def test_a_point_on_the_plane_is_on_its_high_side():
    env = at((0.45, 0.3))
    env.step(UP_X)  # (0.55, 0.3)
    env.step(DOWN_X)  # (0.45, 0.3): through the opening again
    env.reset(options={"start": (0.5, 0.7)})  # on the plane, outside the opening
    assert env.step(UP_X)[1] == -1.0  # stays on the high side
    env.reset(options={"start": (0.5, 0.7)})
    assert env.step(DOWN_X)[1] == -10.0  # crosses to the low side, outside the opening


@pytest.mark.parametrize(
    ("start", "action"),
    [((0.95, 0.5), UP_X), ((0.05, 0.5), DOWN_X), ((0.2, 0.95), UP_Y), ((0.2, 0.0), DOWN_Y), ((1.0, 0.5), UP_X)],
)
def test_leaving_the_cube_is_a_collision(start, action):
    env = at(start)
    _, reward, _, _, info = env.step(action)
    assert reward == -10.0 and info["collision"] is True
    np.testing.assert_array_equal(env.position, start)


def test_reaching_the_goal_gives_ten_and_terminates():
    env = at((0.85, 0.95))
    _, reward, terminated, truncated, info = env.step(UP_X)  # (0.95, 0.95): both >= 0.9
    assert (reward, terminated, truncated, info["collision"]) == (10.0, True, False, False)
    env = at((0.85, 0.75))
    assert env.step(UP_X)[1:3] == (-1.0, False)  # (0.95, 0.75): y below 0.9


def test_goal_in_eight_dimensions_needs_every_coordinate():
    start = (0.95,) * 7 + (0.85,)
    env = at(start, walls=[], dims=8)
    assert env.step(2 * 7 + 1)[1:3] == (-1.0, False)  # down along axis 7: further away
    assert env.step(2 * 7)[1:3] == (-1.0, False)  # back to 0.85
    assert env.step(2 * 7)[1:3] == (10.0, True)  # 0.95


def test_truncates_after_max_steps():
    env = at((0.2, 0.2), max_steps=3)
    assert [env.step(UP_Y)[3] for _ in range(3)] == [False, False, True]
    env.reset(options={"start": (0.2, 0.2)})
    assert env.step(UP_Y)[3] is False and env.elapsed_steps == 1


def test_slip_moves_along_another_axis_with_its_probability():
    env = at((0.5, 0.5, 0.5), walls=[], slip=0.3)
    env.reset(seed=1, options={"start": (0.5, 0.5, 0.5)})
    moves: Counter = Counter()
    n = 20_000
    for _ in range(n):
        env.reset(options={"start": (0.5, 0.5, 0.5)})
        env.step(UP_X)
        delta = np.round((env.position - 0.5) / 0.1).astype(int)
        moves[tuple(delta)] += 1
    assert moves[(1, 0, 0)] / n == pytest.approx(0.7, abs=0.015)
    for other in [(0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]:  # the 2 * (d - 1) other moves, equally likely
        assert moves[other] / n == pytest.approx(0.3 / 4, abs=0.01)
    assert moves[(-1, 0, 0)] == 0 and sum(moves.values()) == n


def test_without_slip_step_draws_nothing():
    env = at((0.2, 0.2))
    state = env.np_random.bit_generator.state
    env.step(UP_X)
    assert env.np_random.bit_generator.state == state


@pytest.mark.parametrize("kwargs", [{"dims": 3}, {"dims": 5, "slip": 0.2, "walls": 10}])
def test_the_same_seed_gives_the_same_episode(kwargs):
    def episode(seed):
        env = SlabMaze(**kwargs)
        env.action_space.seed(seed)
        obs, _ = env.reset(seed=seed)
        rows = [obs]
        for _ in range(200):
            obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            rows.append(np.append(obs, reward))
            if terminated or truncated:
                break
        return rows

    a, b, c = episode(4), episode(4), episode(5)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], c[0])


# -- starts -----------------------------------------------------------------------------------


def test_fixed_start_is_half_a_move_from_the_origin():
    obs, _ = SlabMaze(dims=4, move=0.2, goal_size=0.2, start="fixed").reset(seed=0)
    np.testing.assert_array_equal(obs, np.full(4, 0.1, dtype=np.float32))


def test_random_starts_cover_the_cube_outside_the_goal_and_are_reproducible():
    env = SlabMaze(dims=2, goal_size=0.5)  # the goal is a quarter of the square: many draws fall in it
    starts = np.array([env.reset(seed=s)[0] for s in range(400)])
    assert not np.any(np.all(starts >= 0.5, axis=1))
    assert starts.min() < 0.05 and starts.max() > 0.95
    np.testing.assert_array_equal(env.reset(seed=7)[0], env.reset(seed=7)[0])


def test_start_positions_are_seeded_points_outside_the_goal():
    env = SlabMaze(dims=3, goal_size=0.5)
    points = env.start_positions(50, seed=2)
    assert points.shape == (50, 3) and points.dtype == np.float64
    assert not np.any(np.all(points >= 0.5, axis=1)) and np.all((points >= 0) & (points <= 1))
    env.reset(seed=0)
    np.testing.assert_array_equal(points, env.start_positions(50, seed=2))
    assert not np.array_equal(points, env.start_positions(50, seed=3))


@pytest.mark.parametrize(
    ("start", "match"),
    [
        ((0.5,), "must be 2 numbers"),
        ((0.5, 1.2), "outside the cube"),
        ((0.95, 0.95), "in the goal"),
        ("ab", "2 numbers"),
    ],
)
def test_bad_start_option_raises_naming_it(start, match):
    with pytest.raises(ValueError, match=match):
        SlabMaze().reset(options={"start": start})


# -- mazes: drawn, stated, and the search that checks them -------------------------------------


@pytest.mark.parametrize("d", range(2, 9))
def test_drawn_mazes_lead_to_the_goal_from_every_region(d):
    for walls in (d, 2 * d):
        for seed in range(5):
            env = SlabMaze(dims=d, walls=walls, layout_seed=seed)
            assert len(env.slabs) == walls
            assert regions_reaching_goal(env.slab_arrays, d, env.move).all()


def test_a_seed_gives_one_maze_and_slabs_states_it_again():
    a, b = SlabMaze(dims=4, walls=6, layout_seed=3), SlabMaze(dims=4, walls=6, layout_seed=3)
    assert a.slabs == b.slabs and a.slabs != SlabMaze(dims=4, walls=6, layout_seed=4).slabs
    again = SlabMaze(dims=4, walls=a.slabs)
    for x, y in zip(a.slab_arrays, again.slab_arrays):
        np.testing.assert_array_equal(x, y)
    assert [s[0] for s in a.slabs] == [0, 0, 1, 1, 2, 3]  # slab j across axis j % d, sorted


def search_through_step(env: SlabMaze, start) -> tuple[dict[tuple[float, ...], int], bool]:
    """Least moves from ``start`` to every lattice point, by a breadth-first search through ``step`` (a walk
    ends where ``step`` terminates, in the goal), and whether some walk reached the goal."""
    dist, todo, reached = {tuple(np.round(start, 9)): 0}, deque([np.asarray(start, dtype=np.float64)]), False
    while todo:
        p = todo.popleft()
        for a in range(env.action_space.n):
            env.reset(options={"start": p})
            _, _, terminated, _, _ = env.step(a)
            reached |= terminated
            key = tuple(np.round(env.position, 9))
            if key not in dist:
                dist[key] = dist[tuple(np.round(p, 9))] + 1
                if not terminated:
                    todo.append(env.position)
    return dist, reached


def lattice_reaches_goal(env: SlabMaze, start) -> bool:
    """Whether a walk over the lattice of moves from ``start``, through ``step``, reaches the goal."""
    return search_through_step(env, start)[1]


@pytest.mark.parametrize(("d", "walls"), [(2, 2), (2, 4), (3, 3), (3, 6)])
def test_from_drawn_starts_a_search_through_step_reaches_the_goal(d, walls):
    for seed in range(3):
        env = SlabMaze(dims=d, walls=walls, layout_seed=seed)
        assert all(lattice_reaches_goal(env, p) for p in env.start_positions(4, seed=seed))


# Two slabs leaving a pocket: the slab across x (at 0.5) opens only above y = 0.5, the slab across y
# (at 0.5) only left of x = 0.5; the region x >= 0.5, y < 0.5 leads nowhere.
POCKET = [(0, 0.5, (0, 0.7), (1, 0.9)), (1, 0.5, (0.1, 0), (0.3, 1))]


def test_a_pocket_is_refused_with_random_starts_and_allowed_with_the_fixed_start():
    reached = regions_reaching_goal(SlabMaze(walls=POCKET, start="fixed").slab_arrays, 2, 0.1)
    np.testing.assert_array_equal(reached, [[True, True], [False, True]])  # [x-slice, y-slice]
    with pytest.raises(
        ValueError, match=r"no path to the goal from the region x\[0\] in \[0.5, 1\], x\[1\] in \[0, 0.5\)"
    ):
        SlabMaze(walls=POCKET)
    env = SlabMaze(walls=POCKET, start="fixed")
    assert lattice_reaches_goal(env, (0.05, 0.05)) and not lattice_reaches_goal(env, (0.75, 0.25))


def test_an_opening_narrower_than_a_move_does_not_count():
    narrow = [(0, 0.5, (0, 0.32), (1, 0.38))]
    with pytest.raises(ValueError, match=r"start='fixed': the walls leave no path .* x\[0\] in \[0, 0.5\)"):
        SlabMaze(walls=narrow, start="fixed")


# -- shortest paths over the lattice of moves ----------------------------------------------------


def test_shortest_steps_detours_through_the_opening():
    # From (0.05, 0.85): down to y = 0.35 (5 moves), across to x = 0.95 (9), up to y = 0.95 (6): 20, where
    # without the slab 9 + 1 = 10 would do; from the fixed start 2 up, 9 across, 7 up: 18.
    env = SlabMaze(walls=DOOR)
    assert env.shortest_steps((0.05, 0.85)) == 20
    assert env.shortest_steps() == 18
    dist, points = env.lattice_distances((0.05, 0.85))
    np.testing.assert_allclose(points[0], np.arange(10) * 0.1 + 0.05)
    assert dist[0, 8] == 0 and dist[4, 8] == 4  # (the start; four moves right, against the slab)
    assert dist[5, 8] == 5 + 5 + 5  # (just across the slab: down to the opening, across, up again)
    assert dist[9, 9] == 20 and (dist >= 0).all()


def test_lattice_through_a_start_off_the_default_lattice():
    env = SlabMaze(walls=DOOR)
    dist, points = env.lattice_distances((0.03, 0.53))
    assert dist.shape == (10, 10) and points[1][0] == pytest.approx(0.03) and points[1][-1] == pytest.approx(0.93)
    assert dist[0, 5] == 0 and dist[9, 9] == 2 + 9 + 6  # (to (0.93, 0.93): down to y = 0.33, across, up)
    assert env.shortest_steps((0.03, 0.53)) == 17


@pytest.mark.parametrize("x", [0.0, 0.3, 0.7, 1.0 - 1e-12])
def test_the_lattice_stays_in_the_cube_where_a_start_lies_on_the_moves_own_lattice(x):
    # 0.3 / 0.1 rounds to 2.9999999999999996: three moves down from 0.3 would leave the cube by 6e-17.
    dist, points = SlabMaze(walls=DOOR).lattice_distances((x, 0.05))
    for p in points:
        assert p.min() >= 0.0 and p.max() <= 1.0 and np.allclose(np.diff(p), 0.1)
    assert dist[np.argmin(np.abs(points[0] - x)), 0] == 0 and (dist[:, :9] >= 0).all()


def test_a_pocket_has_no_path_and_its_points_are_unreachable_from_outside():
    env = SlabMaze(walls=POCKET, start="fixed")
    assert env.shortest_steps((0.75, 0.25)) == -1
    dist, points = env.lattice_distances()
    pocket = np.outer(points[0] >= 0.5, points[1] < 0.5)  # ([x, y])
    np.testing.assert_array_equal(dist == -1, pocket)


def test_walks_end_in_the_goal_so_its_far_corner_is_not_reached():
    # No slabs, a goal of side 0.3: its lattice points are 0.75, 0.85, 0.95 on each axis; (0.75, 0.75) is 7 + 7
    # moves from the fixed start, and the walks end there, so (0.95, 0.95), behind other goal points, is never reached.
    env = SlabMaze(walls=[], goal_size=0.3)
    dist, points = env.lattice_distances()
    assert env.shortest_steps() == 14 and dist[7, 7] == 14 and dist[7, 9] == 16 and dist[9, 9] == -1
    assert (dist[:7] >= 0).all() and (dist[:, :7] >= 0).all()


@pytest.mark.parametrize(("d", "walls", "seed"), [(2, 4, 0), (3, 3, 1), (3, 6, 2)])
def test_lattice_distances_agree_with_a_search_through_step(d, walls, seed):
    env = SlabMaze(dims=d, walls=walls, layout_seed=seed)
    start = env.start_positions(1, seed=seed)[0]
    dist, points = env.lattice_distances(start)
    by_step, _ = search_through_step(env, start)
    grid = np.stack(np.meshgrid(*points, indexing="ij"), axis=-1).reshape(-1, d)
    expected = [by_step.get(tuple(np.round(p, 9)), -1) for p in grid]
    np.testing.assert_array_equal(dist.ravel(), expected)
    assert env.shortest_steps(start) == min(v for k, v in by_step.items() if min(k) >= 1 - env.goal_size)


@pytest.mark.parametrize(
    ("kwargs", "start", "match"),
    [
        ({"dims": 8}, None, r"100,000,000 points \(move=0.1, dims=8\), more than the 2,000,000 searched; use a "),
        ({}, (0.95, 0.95), r"is in the goal; choose a point outside it"),
        ({}, (0.5, 1.5), r"is outside the cube"),
    ],
)
def test_shortest_steps_refuses_naming_the_problem_and_the_fix(kwargs, start, match):
    with pytest.raises(ValueError, match=match):
        SlabMaze(**kwargs).shortest_steps(start)


# -- pictures ---------------------------------------------------------------------------------


def test_ansi_shows_the_slice_with_slabs_goal_and_point():
    env = SlabMaze(walls=DOOR, start="fixed", render_mode="ansi")
    env.reset(seed=0)
    rows = [".....|...G"] + [".....|...."] * 5 + [".........."] * 2 + [".....|....", "R....|...."]
    assert env.render() == "\n".join(rows) + "\n"
    assert SlabMaze().render() is None


def test_ansi_in_three_dimensions_shows_slabs_closed_off_by_the_third_coordinate():
    door = [(0, 0.5, (0, 0.2, 0.6), (1, 0.4, 0.8))]  # open only where 0.6 <= z <= 0.8
    env = SlabMaze(dims=3, walls=door, render_mode="ansi")
    env.reset(options={"start": (0.05, 0.05, 0.7)})
    assert env.render().splitlines()[7] == ".........." and env.render().endswith("x[2:] = (0.700)\n")
    env.reset(options={"start": (0.05, 0.05, 0.1)})
    assert env.render().splitlines()[7] == ".....|...."


# -- bad input --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"dims": 1}, "dims must be an integer from 2 to 8"),
        ({"dims": 9}, "dims must be an integer from 2 to 8"),
        ({"dims": 3.0}, "dims must be an integer from 2 to 8"),
        ({"dims": True}, "dims must be an integer from 2 to 8"),
        ({"move": 0.0}, r"move must be in \(0.0, 0.5\], not 0.0"),
        ({"move": 0.6}, r"move must be in \(0.0, 0.5\], not 0.6"),
        ({"goal_size": 0.05}, r"goal_size must be in \[move, 0.5\] = \[0.1, 0.5\] \(at least one move"),
        ({"goal_size": 0.7}, r"goal_size must be in \[move, 0.5\]"),
        ({"opening": 0.05}, r"opening must be in \[move, 1.0\]"),
        ({"slip": -0.1}, r"slip must be in \[0.0, 1.0\), not -0.1"),
        ({"slip": 1.0}, r"slip must be in \[0.0, 1.0\), not 1.0"),
        ({"start": "middle"}, "start must be 'random' or 'fixed'"),
        ({"max_steps": 0}, "max_steps must be an integer >= 1 or None"),
        ({"render_mode": "human"}, "render_mode must be None or 'ansi', not 'human'"),
        ({"layout_seed": -1}, "layout_seed must be an integer >= 0"),
        ({"walls": -1}, "walls must be an integer >= 0, not -1"),
        ({"walls": 2.5}, "walls must be None, a number of slabs or a list of slabs, not 2.5"),
        ({"walls": 100}, "walls=100 puts 50 slabs on axis 0, but only 8 fit .* use at most 16 walls"),
        ({"dims": 3, "walls": [(3, 0.5, (0, 0, 0), (1, 1, 1))]}, r"walls\[0\] has axis 3, but dims=3 has axes 0 to 2"),
        ({"walls": [(0, 0.5, (0, 0), (1, 1)), (0.5, 0.5)]}, r"walls\[1\] must be a slab \(axis, position, low, high\)"),
        ({"walls": [(0, 0.5, (0, 0, 0), (1, 1, 1))]}, r"walls\[0\]: the opening's corners must have 2 numbers each"),
        ({"walls": [(0, 0.05, (0, 0), (1, 1))]}, r"walls\[0\] at position 0.05 on axis 0: slabs must lie in \[move"),
        ({"walls": [(0, 0.95, (0, 0), (1, 1))]}, r"slabs must lie in \[move, 1 - goal_size\] = \[0.1, 0.9\]"),
        ({"walls": [(1, 0.5, (0.6, 0), (0.4, 1))]}, r"walls\[0\]: its opening .* must have 0 <= low <= high <= 1"),
        (
            {"walls": [(0, 0.5, (0, 0), (1, 1)), (0, 0.55, (0, 0), (1, 1))]},
            "two slabs on axis 0, at 0.5 and 0.55, are closer than move=0.1",
        ),
    ],
)
def test_bad_arguments_raise_naming_the_value_and_the_fix(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SlabMaze(**kwargs)


@pytest.mark.parametrize("action", [4, -1, 1.0, True, "0"])
def test_bad_action_raises(action):
    env = SlabMaze()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action must be an integer in \[0, 3\]"):
        env.step(action)


# -- avq's agents run on it -------------------------------------------------------------------


def test_an_avq_agent_learns_on_it_without_error():
    agent = avq.make_agent("avq-plan", SlabMaze(dims=3), seed=0)
    agent.learn(total_episodes=5)
    assert math.isfinite(float(agent.codebook_.sum()))
