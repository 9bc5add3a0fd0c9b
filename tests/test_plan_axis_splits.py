"""``avq-plan``'s cuts across one axis: the outcome split's where one axis carries ``axis_share`` of the gap, and
``collision_cut``, the growth on collisions that cuts a cell where a decision collides from part of it instead of
appending every collision's observation; each set up by hand with the numbers written out."""

import gymnasium as gym
import numpy as np
import pytest
from test_planning import add_cell, plan_agent, remember

import avq
from avq.agents.plan import kernels as core


def two_groups(axis_share):
    """Cell 0 at (2, 2), cell 1 far away at (20, 20). Decision 0 from (1, 1.5) stayed in cell 0, from (3, 2.5) it
    went to cell 1: the two groups' mean starts are (1, 1.5) and (3, 2.5), a squared gap of 4 + 1 = 5, of which
    the x axis carries 4 (a share of 0.8). Cut around the two."""
    agent = plan_agent(axis_share=axis_share)
    add_cell(agent, (2.0, 2.0))
    add_cell(agent, (20.0, 20.0))
    remember(agent, (1.0, 1.5), 0, (1.2, 1.5), -1.0)
    remember(agent, (3.0, 2.5), 0, (20.0, 20.0), -1.0)
    share = -1.0 if axis_share is None else axis_share
    c = core.split_cell(agent._ag, agent._model.a, 0, 0, np.array([1.0, 1.5]), np.array([3.0, 2.5]), share, agent.d_min)
    return agent, c


@pytest.mark.parametrize("axis_share", [0.0, 0.5, 0.8])
def test_the_outcome_split_cuts_across_the_axis_that_carries_the_share_of_the_gap(axis_share):
    agent, c = two_groups(axis_share)
    # Across x alone: the cell's vector (2, 2) moved along x to each mean's x, its y kept.
    assert c == 2
    assert agent._ag.V[0].tolist() == [1.0, 2.0] and agent._ag.V[2].tolist() == [3.0, 2.0]
    # The transition from (3, 2.5) now starts in the new cell; the other stays in cell 0.
    assert agent._ag.mem_i[:2, 1].tolist() == [0, 2]


@pytest.mark.parametrize("axis_share", [0.81, 1.0, None])
def test_below_the_share_the_cut_is_the_bisector_of_the_two_mean_starts(axis_share):
    agent, c = two_groups(axis_share)
    assert c == 2
    assert agent._ag.V[0].tolist() == [1.0, 1.5] and agent._ag.V[2].tolist() == [3.0, 2.5]


def collided(*leaving):
    """Cell 0 at (2, 2), cell 1 at (20, 20); decision 0 left cell 0 for cell 1 from each start in ``leaving``, then
    collided at (3, 2.5) (it stayed there, in cell 0)."""
    agent = plan_agent(collision_growth=False, collision_cut=True)
    add_cell(agent, (2.0, 2.0))
    add_cell(agent, (20.0, 20.0))
    for xs in leaving:
        remember(agent, xs, 0, (20.0, 20.0), -1.0)
    remember(agent, (3.0, 2.5), 0, (3.0, 2.5), -10.0)
    return agent, core.cut_at_collision(agent._ag, agent._model.a, 0, 0, np.array([3.0, 2.5]))


def test_a_collision_cuts_the_cell_across_one_axis_between_where_the_decision_collides_and_where_it_leaves():
    # It left from (1, 2) and (1, 2.2): that successor's mean start is (1, 2.1). From there to the collision at
    # (3, 2.5) x differs most (2 against 0.4): the cell's vector (2, 2) moves along x to 3 and to 1.
    agent, c = collided((1.0, 2.0), (1.0, 2.2))
    assert c == 2
    assert agent._ag.V[0].tolist() == [3.0, 2.0] and agent._ag.V[2].tolist() == [1.0, 2.0]
    assert agent._ag.mem_i[:3, 1].tolist() == [2, 2, 0]  # (the leaving transitions start in the new cell)


def test_a_decision_that_only_ever_collided_is_not_cut():
    agent, c = collided()
    assert c == -1 and agent.n_cells == 2 and agent._ag.V[0].tolist() == [2.0, 2.0]


def test_a_collision_within_d_min_of_where_the_decision_leaves_is_not_cut():
    # From (2.5, 2.2) to (3, 2.5) x differs most, by 0.5: within d_min 1.
    agent = plan_agent(collision_growth=False, collision_cut=True, d_min=1.0)
    add_cell(agent, (2.0, 2.0))
    add_cell(agent, (20.0, 20.0))
    remember(agent, (2.5, 2.2), 0, (20.0, 20.0), -1.0)
    remember(agent, (3.0, 2.5), 0, (3.0, 2.5), -10.0)
    assert core.cut_at_collision(agent._ag, agent._model.a, 0, 0, np.array([3.0, 2.5])) == -1
    assert agent.n_cells == 2


def slab(**kw):
    env = gym.make("avq/SlabMaze-v0", dims=3, move=0.1, layout_seed=3)
    return avq.make_agent("avq", env, seed=0, max_cells=1_000_000, **kw).learn(total_timesteps=20_000)


def test_on_a_maze_of_three_dimensions_the_collision_cut_grows_far_fewer_cells_than_appending_collisions():
    # The paper's growth appends a cell at every collision farther than d_min from every vector: the slabs and the
    # cube's faces are surfaces of two dimensions, which it tiles. The collision split cuts the cells they cross.
    paper = slab()
    split = slab(collision_growth=False, collision_cut=True, axis_share=0.8)
    assert split.n_cells < paper.n_cells / 2


def test_collision_cut_on_both_paths_gives_identical_results():
    out = []
    for fused in (True, False):
        env = gym.make("avq/GridMaze-v0", layout="lau2002")
        agent = avq.make_agent("avq", env, seed=3, fused=fused, collision_growth=False, collision_cut=True)
        agent.learn(total_episodes=30)
        out.append((agent.codebook_, agent.q_, agent.episode_history()["steps"]))
    for x, y in zip(*out):
        assert np.array_equal(x, y)
    # (the rule is at work here: without it, the same run ends with other cells)
    env = gym.make("avq/GridMaze-v0", layout="lau2002")
    plain = avq.make_agent("avq", env, seed=3, collision_growth=False).learn(total_episodes=30)
    assert plain.codebook_.shape != out[0][0].shape or not np.array_equal(plain.codebook_, out[0][0])


def test_collision_cut_resumes_exactly(tmp_path):
    def agent():
        env = gym.make("avq/SlabMaze-v0", dims=3, move=0.1, layout_seed=3)
        return avq.make_agent("avq", env, seed=1, collision_growth=False, collision_cut=True, axis_share=0.8)

    whole = agent().learn(total_episodes=30)
    part = agent().learn(total_episodes=12)
    part.save(tmp_path / "m.zip")
    loaded = avq.load(tmp_path / "m.zip").learn(total_episodes=18)
    assert loaded.collision_cut and loaded.axis_share == 0.8
    assert np.array_equal(whole.codebook_, loaded.codebook_) and np.array_equal(whole.q_, loaded.q_)


@pytest.mark.parametrize(
    "kw, words",
    [
        (dict(collision_cut=True), ["collision_growth=True and collision_cut=True", "collision_growth=False"]),
        (dict(collision_growth=False, collision_cut="yes"), ["collision_cut", "'yes'"]),
        (dict(axis_share=1.5), ["axis_share", "1.5"]),
        (dict(axis_share=-0.1), ["axis_share", "-0.1"]),
    ],
)
def test_bad_axis_split_options_get_a_clear_error(kw, words):
    with pytest.raises(ValueError) as err:
        avq.PlanningAVQ(gym.make("MountainCar-v0"), **kw)
    for w in words:
        assert w in str(err.value)
