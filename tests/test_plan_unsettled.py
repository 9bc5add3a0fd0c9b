"""``outcome_split="unsettled"``: the outcome split also compares outcomes that end in cells not yet settled whose
values owe nothing to optimism (a decision they know is worth more than an untried one), as near a goal worth more
than ``v_opt``, where no untried decision is worth trying and cells never settle; set up by hand with the numbers
written out, and on the slab maze where the default's split never fires beside the goal."""

import gymnasium as gym
import numpy as np
import pytest
from test_planning import add_cell, model, observe, plan_agent, remember

import avq
from avq.agents.plan import explore, kernels as core, model as _model


def test_a_value_owes_no_optimism_once_a_known_decision_is_worth_more_than_an_untried_one():
    mdl = model(v_opt=10.0, known=1, states=3)
    # State 0: action 0 known, worth 12 (above v_opt), action 1 untried: trying it cannot raise V(0).
    observe(mdl, 0, 0, 12.0, 1.0, -1)
    # State 1: action 0 known, worth 4, action 1 untried (worth 10): V(1) is its optimism.
    observe(mdl, 1, 0, 4.0, 1.0, -1)
    assert not _model.settled(mdl.a, 0) and explore.owes_no_optimism(mdl.a, 0)
    assert not explore.owes_no_optimism(mdl.a, 1)
    # State 2: action 0 known, worth exactly 10, action 1 untried (10): the explorer breaks the tie at random and
    # may still try it, so V(2) may yet owe it something.
    observe(mdl, 2, 0, 10.0, 1.0, -1)
    assert not explore.owes_no_optimism(mdl.a, 2)
    observe(mdl, 1, 1, 3.0, 1.0, -1)  # every action known: settled
    assert _model.settled(mdl.a, 1) and explore.owes_no_optimism(mdl.a, 1)
    assert explore.owes_no_optimism(mdl.a, -1)  # (the terminal state)


@pytest.mark.parametrize("outcome_split, compared", [(True, False), ("unsettled", True)])
def test_disagreement_counts_an_unsettled_successor_whose_value_owes_no_optimism_only_when_asked(
    outcome_split, compared
):
    agent = plan_agent(outcome_split=outcome_split)
    for x in ((1.0, 1.0), (5.0, 5.0), (5.0, 1.0)):
        add_cell(agent, x)
    m = agent._model.a
    assert m.MP[_model.ModelParam.V_OPT] == 10.0
    # Cell 1: action 0 known, worth 16; the other three untried (10). Cell 2 settled at -20.
    m.cnt[1, 0], m.Q[1, 0], m.V[1] = 1, 16.0, 16.0
    for a in range(4):
        m.cnt[2, a], m.Q[2, a] = 1, -20.0
    m.V[2] = -20.0
    remember(agent, (1, 1), 1, (5, 5), -2.0)  # cell 0, action 1, to cell 1 from (1, 1): outcome -2 + 16 = 14
    out = np.zeros(3)
    # From (2, 1) to cell 2: outcome -21. Gap 35, distance 1, slope 3: excess 32, when cell 1 is compared.
    agent._ag.xs[:] = 2.0, 1.0
    excess = core.disagreement(agent._ag, m, 0, 1, -21.0, 3.0, out)
    if compared:
        assert excess == pytest.approx(32.0) and out.tolist() == [1.0, 1.0, -21.0]
    else:
        assert excess == -np.inf
    # Worth 8 (below v_opt 10): its value is its optimism, and no setting compares it.
    m.Q[1, 0], m.V[1] = 8.0, 10.0
    assert core.disagreement(agent._ag, m, 0, 1, -21.0, 3.0, out) == -np.inf


def greedy_success(agent, maze, starts):
    """The share of ``starts`` from which the greedy policy reaches the goal within the maze's step limit."""
    reached = 0
    for x in starts:
        obs, _ = maze.reset(options={"start": x})
        for _ in range(maze.max_steps):
            obs, _, terminated, truncated, _ = maze.step(int(agent.predict(obs, deterministic=True)[0]))
            if terminated or truncated:
                break
        reached += terminated
    return reached / len(starts)


def test_on_the_slab_maze_the_unsettled_outcomes_reach_90_percent_where_the_default_does_not_in_7000_steps():
    # Seed 110 of the 2-dimensional slab maze: with the default the agent goes back and forth between two cells
    # beside the goal's (in the benchmark, still at 62% after 200,000 steps); the cells that lead to the goal keep
    # an untried decision (worth 0, below their way to the goal), never settle, and the split never compares them.
    # (Greedy policies are unsteady between budgets: with the option 80%, 34% and 96% after 2,000, 5,000 and
    # 6,000 steps, 70% to 98% from 7,000 to 12,000; without it 6% to 78% from 2,500 to 12,000.)
    def run(outcome_split):
        env = gym.make("avq/SlabMaze-v0", dims=2, move=0.1, layout_seed=2, start="random")
        agent = avq.make_agent("avq", env, seed=110, outcome_split=outcome_split).learn(total_timesteps=7_000)
        maze = gym.make("avq/SlabMaze-v0", dims=2, move=0.1, layout_seed=2).unwrapped
        return greedy_success(agent, maze, maze.start_positions(50, seed=1))

    assert run("unsettled") >= 0.9
    assert run(True) < 0.9


def test_where_every_reward_is_a_cost_the_option_changes_nothing():
    # MountainCar: -1 a step, so v_opt "auto" is 0 and every known decision is worth less: no cell's value owes
    # nothing to optimism but a settled one's, and the split compares what the default compares, run for run.
    # (A known decision worth exactly v_opt, where "more than" and "at least" differ, is the first test's.)
    def run(outcome_split):
        agent = avq.make_agent("avq", gym.make("MountainCar-v0"), seed=3, outcome_split=outcome_split)
        return agent.learn(total_timesteps=6_000)

    new, old = run("unsettled"), run(True)
    q = new.q_
    assert new.v_opt_ == 0.0 and np.all((q < 0.0) | (q == 0.0)) and (q < 0.0).any()  # (0: untried, worth v_opt)
    assert new.n_cells > 1 and np.array_equal(new.codebook_, old.codebook_) and np.array_equal(new.q_, old.q_)


def test_unsettled_outcomes_resume_exactly_and_a_bad_value_gets_a_clear_error(tmp_path):
    def agent():
        env = gym.make("avq/SlabMaze-v0", dims=2, move=0.1, layout_seed=2, start="random")
        return avq.make_agent("avq", env, seed=110, outcome_split="unsettled")

    whole = agent().learn(total_episodes=30)
    part = agent().learn(total_episodes=12)
    part.save(tmp_path / "m.zip")
    loaded = avq.load(tmp_path / "m.zip").learn(total_episodes=18)
    assert loaded.outcome_split == "unsettled"
    assert np.array_equal(whole.codebook_, loaded.codebook_) and np.array_equal(whole.q_, loaded.q_)
    with pytest.raises(ValueError) as err:
        avq.PlanningAVQ(gym.make("MountainCar-v0"), outcome_split="yes")
    for w in ("outcome_split", "'yes'", "'unsettled'"):
        assert w in str(err.value)
