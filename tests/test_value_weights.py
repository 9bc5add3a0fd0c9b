"""The metric weighted by the slopes of the planned values (``reweight_when_full``, avq.agents._value_weights):
the fit and the weights on points set by hand, and the agent applying them once, when its codebook is full;
saved and resumed exactly."""

import io
import zipfile

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq.agents._value_weights import FLOOR, MIN_CELLS, NEIGHBOURS, SETTLED_SHARE, slope_weights, value_slopes


def test_the_slope_is_found_along_the_dimension_the_value_follows_and_zero_along_the_other():
    # A grid of 6 x 6 points, spaced 1 and 2; the value rises by 3 a unit along z0 and ignores z1: every pair of
    # neighbours has |dV| = 3 |dz0| exactly, whatever their gap along z1.
    z = np.array([(i, 2.0 * j) for i in range(6) for j in range(6)], dtype=float)
    slopes = value_slopes(z, 3.0 * z[:, 0])
    assert slopes == pytest.approx([3.0, 0.0], abs=1e-9)
    # Along the other axis, 0.5 a unit: the slopes swap.
    assert value_slopes(z, 0.5 * z[:, 1]) == pytest.approx([0.0, 0.5], abs=1e-9)
    assert NEIGHBOURS == 5


def test_the_slopes_add_where_each_pair_of_neighbours_differs_along_one_axis():
    # Points on the two axes only (a cross), 1 apart: each point's nearest differ from it along one axis, or
    # along both by the same amount at the centre. V = 2 |z0| + 7 |z1| is linear along each arm.
    arm = np.arange(1.0, 8.0)
    z = np.vstack([[0.0, 0.0], np.column_stack([arm, 0 * arm]), np.column_stack([0 * arm, arm])])
    values = 2.0 * z[:, 0] + 7.0 * z[:, 1]
    assert value_slopes(z, values, neighbours=2) == pytest.approx([2.0, 7.0], abs=1e-9)


def test_the_weights_are_the_slopes_over_the_largest_floored_with_a_product_of_one():
    w = slope_weights(np.array([4.0, 1.0, 0.0]))
    raw = np.array([1.0, 0.25, FLOOR])
    assert FLOOR == 0.1
    assert w == pytest.approx(raw / np.prod(raw) ** (1 / 3))
    assert np.prod(w) == pytest.approx(1.0)
    assert w == pytest.approx([3.420, 0.855, 0.342], abs=1e-3)
    assert slope_weights(np.zeros(3)).tolist() == [1.0, 1.0, 1.0]


def watched(agent):
    """``agent``'s settled cells and their values each time the rule asks for them (the agent's own method)."""
    seen = []
    own = agent._settled_values

    def settled_values():
        seen.append((own(), agent.scale_))
        return seen[-1][0]

    agent._settled_values = settled_values
    return seen


def test_the_metric_is_weighted_once_when_the_codebook_is_full_and_most_cells_are_settled():
    agent = avq.PlanningAVQ(gym.make("MountainCar-v0"), seed=0, max_cells=60)
    assert agent.reweight_when_full and SETTLED_SHARE == 0.75 and MIN_CELLS == 20
    seen = watched(agent)
    start = None
    for _ in range(200):
        agent.learn(total_episodes=1)
        if start is None:
            start = agent.scale_  # (the bounds' ranges: MountainCar's are finite)
        assert agent.n_cells >= 60 or not seen  # (asked only once the codebook is full)
        if agent._weighted:
            break
    assert agent._weighted
    # Asked at every episode's end since the codebook filled; weighted the first time three quarters of the cells
    # (and at least 20) were settled.
    for (_, values, cells), _ in seen[:-1]:
        assert cells == 60 and len(values) < max(MIN_CELLS, SETTLED_SHARE * cells)
    ((vectors, values, cells), before), *_ = seen[-1:]
    assert len(values) >= max(MIN_CELLS, SETTLED_SHARE * cells) and np.array_equal(before, start)
    weights = slope_weights(value_slopes(vectors / before, values))
    assert agent.scale_ == pytest.approx(before / weights)
    assert np.prod(before / agent.scale_) == pytest.approx(1.0)  # (the cells' volume is kept)
    assert not np.allclose(weights, 1.0)
    # Once: later episodes do not ask again, and the scale stays.
    asked, scale = len(seen), agent.scale_
    agent.learn(total_episodes=3)
    assert len(seen) == asked and np.array_equal(agent.scale_, scale)
    # The model follows its remembered transitions into the cells of the new metric.
    t = int(agent._ag.S[avq.agents.plan.state.MEM_N])
    assert np.array_equal(agent._ag.mem_i[:t, 1], agent.cells(agent._ag.mem_x[:t, :2]))


def test_with_fewer_settled_cells_than_needed_nothing_changes_and_it_is_tried_again():
    agent = avq.PlanningAVQ(gym.make("MountainCar-v0"), seed=0, max_cells=MIN_CELLS // 2)
    seen = watched(agent)
    start = agent.learn(total_episodes=1).scale_
    agent.learn(total_episodes=4)
    assert agent.n_cells == MIN_CELLS // 2 and len(seen) >= 2
    assert np.array_equal(agent.scale_, start) and not agent._weighted


def test_off_it_never_asks_and_the_maze_entries_keep_it_off_for_their_fused_loop():
    agent = avq.PlanningAVQ(gym.make("MountainCar-v0"), seed=0, max_cells=20, reweight_when_full=False)
    seen = watched(agent)
    start = agent.learn(total_episodes=1).scale_
    agent.learn(total_episodes=5)
    assert agent.n_cells == 20 and not seen and np.array_equal(agent.scale_, start)
    for task in ("avq/GridMaze-v0", "avq/RobotMaze-v0"):
        assert avq.make_agent("avq", task, seed=0).get_params()["reweight_when_full"] is False
    assert avq.make_agent("avq", "Acrobot-v1", seed=0).get_params()["reweight_when_full"] is True


@pytest.mark.parametrize("first", [10, 55])  # saved before the metric is weighted, and after
def test_a_run_resumes_exactly_across_the_weighting(tmp_path, first):
    make = lambda: avq.PlanningAVQ(gym.make("CartPole-v1"), seed=3, max_cells=80)  # noqa: E731
    whole = make().learn(total_episodes=70)
    part = make().learn(total_episodes=first)
    loaded = avq.load(part.save(tmp_path / "m.zip")).learn(total_episodes=70 - first)
    assert whole._weighted and (part._weighted == (first == 55))
    assert np.array_equal(loaded.scale_, whole.scale_) and np.array_equal(loaded.codebook_, whole.codebook_)
    assert np.array_equal(loaded.q_, whole.q_)
    assert loaded.episode_history()["return"].tolist() == whole.episode_history()["return"].tolist()


def test_bad_weights_in_a_file_and_a_bad_setting_get_clear_errors(tmp_path):
    agent = avq.PlanningAVQ(gym.make("MountainCar-v0"), seed=0, max_cells=40).learn(total_episodes=20)
    assert agent._weighted
    path = agent.save(tmp_path / "m.zip")
    with zipfile.ZipFile(path) as zf:
        files = {name: zf.read(name) for name in zf.namelist()}
    with np.load(io.BytesIO(files["arrays.npz"])) as npz:
        arrays = {k: npz[k] for k in npz.files}
    assert np.prod(arrays["metric_weights"]) == pytest.approx(1.0)
    arrays["metric_weights"] = np.array([1.0, -1.0])
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    files["arrays.npz"] = buf.getvalue()
    bad = tmp_path / "bad.zip"
    with zipfile.ZipFile(bad, "w") as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    with pytest.raises(ValueError, match=r"metric_weights \[1.0, -1.0\] must hold one number > 0 per dimension"):
        avq.load(bad)
    assert avq.load(path).get_params() == agent.get_params()  # (the file given is left as it was)
    with pytest.raises(ValueError, match="reweight_when_full"):
        avq.PlanningAVQ(gym.make("MountainCar-v0"), reweight_when_full="yes")
