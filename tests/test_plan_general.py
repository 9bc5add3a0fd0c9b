"""``avq-plan`` on tasks without collisions: growth where a decision stays too long in its cell
(``split_after``), R-max's optimism from the rewards seen (``v_opt="auto"``) and the metric estimated from the
observations (``scale="auto"``), each set up by hand with the numbers written out; saved and resumed exactly."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq.agents.plan import model as _model, tabular
from avq.agents.plan.memory import COMPOSED, HELD
from avq.agents.plan.state import MEM_N, UNLIMITED_HORIZON, auto_v_opt, best_return_to_go, horizon, value_ceiling

from conftest import ScriptedEnv

NO = False


def walk(xs, last_reward=-1.0, reward=-1.0):
    """A 1-D episode through the positions ``xs`` (``reward`` a step), ending at the last."""
    return [((x,), last_reward if k == len(xs) - 1 else reward, k == len(xs) - 1, NO, NO) for k, x in enumerate(xs)]


def line_agent(steps, **kw):
    params = dict(scale=1.0, d_min=0.5, collision_growth=False, outcome_split=False, split_after=3, seed=0)
    params.update(kw)
    return avq.PlanningAVQ(ScriptedEnv([((0.0,), steps)], n_actions=1, dims=1), **params)


#: From x = 0: three steps in cell 0 (the third 1.0 away, beyond d_min 0.5), three more that stay within d_min
#: of x = 1, one to 2.0 (the fourth step of that decision), and the end at 2.1.
LINE = walk([0.1, 0.2, 1.0, 1.1, 1.2, 1.3, 2.0, 2.1])


def test_a_decision_that_stays_split_after_steps_in_its_cell_gives_the_observation_a_cell():
    agent = line_agent(LINE).learn(total_episodes=1)
    assert agent.codebook_.ravel().tolist() == [0.0, 1.0, 2.0]
    # The transitions: 0 -> 1 (3 steps), 1 -> 2 (4 steps: x = 1.1-1.3 lie within d_min of 1.0, so the decision
    # went on past split_after), 2 -> the end (1 step). The last column: the first two ended because the cell
    # changed (crossings), held (HELD: compose_crossings="noise", the default), the third because the episode did.
    assert agent._ag.mem_i[:3].tolist() == [[0, 0, 1, HELD], [0, 1, 2, HELD], [0, 2, -1, 0]]
    assert agent._ag.mem_f[:3, 0].tolist() == [-3.0, -4.0, -1.0]
    # With merging on, the crossings go on where their two ends come to lie in one cell (COMPOSED); without
    # compose_crossings none is kept.
    merging = line_agent(LINE, rho=1.0).learn(total_episodes=1)
    assert merging._ag.mem_i[:3, 3].tolist() == [COMPOSED, COMPOSED, 0]
    assert line_agent(LINE, compose_crossings=False).learn(total_episodes=1)._ag.mem_i[:3, 3].tolist() == [0, 0, 0]
    h = agent.episode_history()
    assert h["decisions"].tolist() == [3] and h["n_cells"].tolist() == [3] and h["refused"].tolist() == [0]


def test_without_split_after_a_task_without_collisions_keeps_one_cell():
    agent = line_agent(LINE, split_after=None).learn(total_episodes=1)
    assert agent.n_cells == 1 and agent.episode_history()["decisions"].tolist() == [1]


def test_at_the_budget_the_growth_is_refused_once_per_decision():
    agent = line_agent(LINE, max_cells=2).learn(total_episodes=1)
    assert agent.codebook_.ravel().tolist() == [0.0, 1.0]
    h = agent.episode_history()
    # The second decision reaches its third step at 1.3 (within d_min: no growth asked), then at 2.0 (its
    # fourth step) asks and is refused; 2.1 is its fifth step, not counted again.
    assert h["refused"].tolist() == [1] and h["decisions"].tolist() == [2]


def test_split_after_is_checked():
    env = ScriptedEnv([((0.0,), LINE)], n_actions=1, dims=1)
    with pytest.raises(ValueError, match="split_after must be an integer >= 1 or None, not 0"):
        avq.PlanningAVQ(env, split_after=0)


# -- v_opt="auto" -------------------------------------------------------------------------------------


def test_the_horizon_is_the_time_limit_else_one_over_one_minus_gamma():
    assert horizon(gym.make("CartPole-v1"), 1.0) == 500.0
    # Discounted: the most 500 steps of reward 1 are worth, 1 + 0.9 + ... + 0.9 ** 499 (not 500).
    assert horizon(gym.make("CartPole-v1"), 0.9) == pytest.approx(sum(0.9**k for k in range(500)))
    assert horizon(gym.make("CartPole-v1", max_episode_steps=3), 0.5) == pytest.approx(1.75)
    env = ScriptedEnv([((0.0,), LINE)], n_actions=1, dims=1)  # (no time limit)
    assert horizon(env, 0.9) == pytest.approx(10.0)
    assert horizon(env, 1.0) == UNLIMITED_HORIZON


def auto_agent(*episodes):
    return avq.PlanningAVQ(
        ScriptedEnv([((0.0,), steps) for steps in episodes], n_actions=2, dims=1),
        scale=1.0,
        d_min=0.5,
        gamma=0.9,
        v_opt="auto",
        collision_growth=False,
        outcome_split=False,
        split_after=3,
        seed=0,
    )


def test_auto_optimism_is_the_horizon_times_the_largest_reward_seen():
    # Two actions, gamma 0.9 (horizon 10), one episode whose rewards are 0 then 2: untried pairs are worth
    # 0 during it (no reward > 0 seen yet), then 10 * 2 = 20.
    agent = auto_agent(walk([0.1, 0.2, 1.0, 1.1], last_reward=2.0, reward=0.0))
    assert agent.v_opt_ == 0.0
    agent.learn(total_episodes=1)
    assert agent.v_opt_ == pytest.approx(20.0)
    m = agent.model_.a
    untried = m.cnt[: agent.n_cells] < 1
    assert untried.any() and np.allclose(agent.q_[untried], 20.0)


def test_auto_optimism_is_zero_once_rewards_of_both_signs_were_seen(tmp_path):
    # The episode above, then one whose rewards are -1 then 2 (shaped: both signs): from 20 down to 0, and the
    # untried pairs with it.
    agent = auto_agent(walk([0.1, 0.2, 1.0, 1.1], last_reward=2.0, reward=0.0), walk([0.1, 1.0], last_reward=2.0))
    agent.learn(total_episodes=1)
    assert agent.v_opt_ == pytest.approx(20.0)
    agent.learn(total_episodes=1)
    assert agent.v_opt_ == 0.0
    untried = agent.model_.a.cnt[: agent.n_cells] < 1
    assert untried.any() and np.all(agent.q_[untried] == 0.0)
    # Saved and loaded, the agent remembers the reward below 0: the next episode (0s and 2) leaves it at 0.
    agent.save(tmp_path / "a.zip")
    loaded = avq.load(tmp_path / "a.zip", env=agent.env)
    assert loaded.learn(total_episodes=1).v_opt_ == 0.0 and agent.learn(total_episodes=1).v_opt_ == 0.0
    assert auto_v_opt(10.0, 0.0, 2.0) == 20.0 and auto_v_opt(10.0, -0.5, 2.0) == 0.0
    assert auto_v_opt(10.0, np.inf, -np.inf) == 0.0 and auto_v_opt(10.0, -3.0, -1.0) == 0.0


def test_the_best_return_to_go_is_the_largest_return_from_any_step_to_the_end():
    # Rewards -1, 5, -2, 3: from each step to the end, gamma 1: 5, 6, 1, 3; gamma 0.5: 1.375, 4.75, -0.5, 3.
    assert best_return_to_go([-1.0, 5.0, -2.0, 3.0], 1.0) == 6.0
    assert best_return_to_go([-1.0, 5.0, -2.0, 3.0], 0.5) == pytest.approx(4.75)
    assert best_return_to_go([], 1.0) == -np.inf


def test_the_ceiling_of_values_holds_only_once_rewards_of_both_signs_were_seen():
    assert value_ceiling(-1.0, 5.0, 6.0) == 6.0 and value_ceiling(-1.0, 5.0, -3.0) == 0.0
    assert value_ceiling(0.0, 5.0, 6.0) == np.inf and value_ceiling(-1.0, -0.5, -3.0) == np.inf


def test_a_ceiling_stops_a_loop_at_a_gain_from_growing_without_end():
    # One state whose one action comes back to it with return 1 (gamma 1): Q = 1 + Q, without end.
    mdl = _model.Model(1, 0.0, -100.0, 1, 1e-9)
    mdl.add_state()
    mdl.reserve(edges=1)
    _model.record(mdl.a, 0, 0, 1.0, 1.0, 0, 1)
    mdl.set_optimism(0.0, 10.0)
    mdl.sweep(1000)
    assert mdl.a.Q[0, 0] == 10.0 and mdl.queued == 0
    mdl.set_optimism(0.0)  # (no ceiling: one backup of every state, then a hundred more: 111)
    mdl.sweep(100)
    assert mdl.a.Q[0, 0] == 111.0 and mdl.a.MP[_model.ModelParam.V_MAX] == _model.NO_CEILING


def test_auto_optimism_caps_values_at_the_best_return_to_go_on_shaped_rewards_and_resumes_exactly(tmp_path):
    # Rewards -1 a step, 2 at the end of the first episode and 3 of the second: from any step to the end at most
    # 2 (the last step of the first), then 3; every planned value no higher.
    episodes = (walk([0.1, 0.2, 1.0, 1.1], last_reward=2.0), walk([0.1, 1.0, 1.1, 2.0, 2.1], last_reward=3.0))
    agent = auto_agent(*episodes)
    agent.learn(total_episodes=1)
    assert agent.model_.a.MP[_model.ModelParam.V_MAX] == 2.0 and agent.q_.max() <= 2.0
    agent.learn(total_episodes=3)
    assert agent.model_.a.MP[_model.ModelParam.V_MAX] == 3.0 and agent.q_.max() <= 3.0
    # Saved inside an episode, the file holds that episode's rewards so far and the best return to go.
    half = auto_agent(*episodes).learn(total_timesteps=11)  # (two episodes of 4 and 5 steps, two of the third)
    assert half.in_episode and half._ep_rewards == [-1.0, -1.0]
    loaded = avq.load(half.save(tmp_path / "half.zip"), env=auto_agent(*episodes).env)
    assert loaded._ep_rewards == [-1.0, -1.0] and loaded._to_go_max == 3.0 and loaded._r_min == -1.0


def test_auto_optimism_on_a_maze_is_the_same_on_both_paths():
    # GridMaze's rewards take both signs (-1 a move, -10 a bump, +10 at the goal); the fused loop sees no rewards
    # in Python, so with v_opt="auto" the agent steps the maze from Python whatever fused says.
    runs = [
        avq.make_agent("avq-plan", gym.make("avq/GridMaze-v0"), seed=3, v_opt="auto", fused=f).learn(total_episodes=20)
        for f in (True, False)
    ]
    assert runs[0].v_opt_ == runs[1].v_opt_ == 0.0
    assert runs[0].model_.a.MP[_model.ModelParam.V_MAX] == runs[1].model_.a.MP[_model.ModelParam.V_MAX] <= 10.0
    assert np.array_equal(runs[0].q_, runs[1].q_) and runs[0].num_timesteps == runs[1].num_timesteps


def test_all_negative_rewards_keep_auto_optimism_at_zero():
    agent = line_agent(LINE, v_opt="auto").learn(total_episodes=2)
    assert agent.v_opt_ == 0.0


def test_changing_optimism_reaches_the_predecessors_of_an_untried_state():
    # States 0 -> 1 by action 0 (return -1, gamma^k 1); state 1 untried. Q[0, 0] = -1 + V(1) = -1 + v_opt.
    mdl = _model.Model(2, 0.0, -100.0, 1, 1e-9)
    for _ in range(2):
        mdl.add_state()
    mdl.reserve(edges=1)
    tabular.observe(mdl.a, 0, 0, -1.0, 1.0, 1, 100)
    assert mdl.a.Q[0, 0] == -1.0
    mdl.set_optimism(5.0)
    mdl.sweep(100)
    assert mdl.a.Q[0, 0] == 4.0 and mdl.a.Q[0, 1] == 5.0 and mdl.a.V[1] == 5.0
    mdl.set_optimism(3.0)  # (and lowering it reaches them too)
    mdl.sweep(100)
    assert mdl.a.Q[0, 0] == 2.0 and mdl.a.Q[0, 1] == 3.0 and mdl.a.V[1] == 3.0


def test_bad_v_opt_gets_a_clear_error():
    with pytest.raises(ValueError, match="v_opt must be .* or 'auto', not 'lots'"):
        avq.make_agent("avq-plan", "CartPole-v1", v_opt="lots")
    with pytest.raises(ValueError, match="v_opt must be"):
        avq.make_agent("tabular-ps", "avq/GridMaze-v0", v_opt="auto")  # (auto is avq-plan's alone)


# -- scale="auto" -------------------------------------------------------------------------------------


def test_the_model_follows_its_transitions_into_the_cells_of_the_new_metric():
    agent = avq.make_agent("avq-plan", "CartPole-v1", seed=0, scale_warmup=400).learn(total_episodes=40)
    assert agent.get_params()["obs_bounds"] is None
    n, size = 4, agent.n_cells
    t = int(agent._ag.S[MEM_N])
    assert agent.n_cells > 1 and t > 0
    starts, ends = agent._ag.mem_x[:t, :n], agent._ag.mem_x[:t, n:]
    assert np.array_equal(agent._ag.mem_i[:t, 1], agent.cells(starts))
    live = agent._ag.mem_i[:t, 2] >= 0
    assert np.array_equal(agent._ag.mem_i[:t, 2][live], agent.cells(ends[live]))
    # The model's counts are those of the remembered transitions in their current cells.
    counts = np.zeros((size, agent.n_actions), dtype=np.int64)
    np.add.at(counts, (agent._ag.mem_i[:t, 1], agent._ag.mem_i[:t, 0]), 1)
    assert np.array_equal(agent.model_.a.cnt[:size], counts)


@pytest.mark.parametrize("first", [3, 30])  # saved during the warm-up (400 observations), and after it
def test_avq_plan_resumes_exactly_on_a_task_without_bounds(tmp_path, first):
    make = lambda: avq.make_agent("avq-plan", "CartPole-v1", seed=2, scale_warmup=400)  # noqa: E731
    whole = make().learn(total_episodes=40)
    part = make().learn(total_episodes=first)
    loaded = avq.load(part.save(tmp_path / "m.zip")).learn(total_episodes=40 - first)
    assert np.array_equal(loaded.scale_, whole.scale_) and loaded.v_opt_ == whole.v_opt_
    assert np.array_equal(loaded.codebook_, whole.codebook_) and np.array_equal(loaded.q_, whole.q_)
    assert loaded.episode_history()["return"].tolist() == whole.episode_history()["return"].tolist()


def test_the_class_defaults_are_those_of_avq_on_tasks_without_collisions():
    direct = avq.PlanningAVQ(gym.make("MountainCar-v0"), seed=0)
    made = avq.make_agent("avq", "MountainCar-v0", seed=0)
    assert direct.get_params() == made.get_params()
    direct.learn(total_episodes=30)
    assert direct.n_cells > 10  # (split_after grows cells; with it off the agent keeps its first cell)
    assert np.array_equal(direct.q_, made.learn(total_episodes=30).q_)
