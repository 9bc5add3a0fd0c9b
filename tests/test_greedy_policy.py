"""The greedy policy of the agents that plan over a learned model (agents/plan/exploit.py): the model's plan
with every pair not yet known worth the floor (the lowest return of an episode seen, no less than ``v_min``)
instead of ``v_opt``; learning is unchanged."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq.agents._history import EpisodeHistory
from avq.agents.plan import tabular
from avq.agents.plan.exploit import greedy_actions, greedy_ceiling, greedy_floor, plan_without_optimism
from avq.agents.plan.model import BACKUPS, Model


def model(m=2, v_opt=10.0, v_min=-100.0, known=1, tol=1e-9, states=3):
    mdl = Model(m, v_opt, v_min, known, tol)
    for _ in range(states):
        mdl.add_state()
    return mdl


def observe(mdl, s, a, r, s2):
    mdl.reserve(edges=1)
    return tabular.observe(mdl.a, s, a, r, 1.0, s2, 1000)


def greedy(mdl, max_sweeps=1000, floor=-np.inf):
    q, v = np.empty_like(mdl.a.Q), np.empty_like(mdl.a.V)
    sweeps = plan_without_optimism(mdl.a, q, v, max_sweeps, floor)
    return q[: mdl.n_states], v[: mdl.n_states], sweeps


def test_a_decision_towards_untried_ones_is_worth_what_was_seen_not_what_is_hoped():
    mdl = model()
    # (0, 0) -> state 1 (return -1), whose decisions are untried; (0, 1) -> the end with return 5.
    observe(mdl, 0, 0, -1.0, 1)
    observe(mdl, 0, 1, 5.0, -1)
    # Planned with optimism: Q(0, 0) = -1 + v_opt = 9 beats 5, so the exploring agent goes to state 1.
    assert mdl.a.Q[0].tolist() == [9.0, 5.0]
    q, v, _ = greedy(mdl)
    # Without it: state 1 is worth v_min = -100, Q(0, 0) = -1 - 100 floored at -100; the greedy choice is 1.
    assert q[0].tolist() == [-100.0, 5.0] and v[1] == -100.0 and v[0] == 5.0
    assert mdl.a.Q[0].tolist() == [9.0, 5.0]  # (the model's own values are left as they were)
    # With a floor of -30 (the lowest return seen) state 1 is worth -30 and Q(0, 0) = -31; below v_min, v_min.
    q, v, _ = greedy(mdl, floor=-30.0)
    assert q[0].tolist() == [-31.0, 5.0] and v[1] == -30.0
    assert greedy(mdl, floor=-1000.0)[1][1] == -100.0


def test_the_floor_is_the_lowest_return_seen_no_higher_than_0():
    assert greedy_floor(None) == -np.inf and greedy_floor(-852.7) == -852.7 and greedy_floor(9.0) == 0.0
    history = EpisodeHistory()
    assert history.lowest_return() is None
    for k, ret in enumerate((-120.5, -852.7, 40.0)):
        history.append(dict(episode=k + 1, steps=10, **{"return": ret}, n_cells=1, appends=0, merges=0, refused=0,
                            decisions=1, wall_s=0.0))  # fmt: skip
    assert history.lowest_return() == -852.7


def test_a_rare_path_into_the_unknown_no_longer_outweighs_a_crash():
    # What the greedy policy met on LunarLander-v3: from state 0, action 0 ends the episode at once at -100 (a
    # crash); action 1 leads 49 times of 50 to state 1, whose action 0 ends it at +100 (a landing), and once to
    # state 2, whose decisions are all untried. v_min -10,000: action 1 is worth 0.98 * 100 + 0.02 * -10,000 =
    # -102, below the crash. With the lowest return seen as the floor (-300): 0.98 * 100 + 0.02 * -300 = 92.
    mdl = model(m=2, v_opt=100.0, v_min=-10_000.0, known=1, states=3)  # (v_opt: R-max's bound, the ceiling)
    observe(mdl, 0, 0, -100.0, -1)
    for k in range(50):
        observe(mdl, 0, 1, 0.0, 2 if k == 0 else 1)
    observe(mdl, 1, 0, 100.0, -1)
    observe(mdl, 1, 1, -100.0, -1)
    q, _, _ = greedy(mdl)
    assert q[0] == pytest.approx([-100.0, -102.0])
    q, _, _ = greedy(mdl, floor=-300.0)
    assert q[0] == pytest.approx([-100.0, 92.0])
    assert greedy_actions(mdl.a)[0] == 0 and greedy_actions(mdl.a, -300.0)[0] == 1


def test_the_greedy_values_are_the_planned_ones_where_every_pair_is_known():
    mdl = model(states=3)
    # A chain 0 -> 1 -> 2 -> end under action 0 (return -1 each), action 1 from each to the end with -20.
    for s in range(3):
        observe(mdl, s, 1, -20.0, -1)
        observe(mdl, s, 0, -1.0, s + 1 if s < 2 else -1)
    mdl.sweep(1000)
    q, v, sweeps = greedy(mdl)
    assert np.array_equal(q, mdl.a.Q[:3]) and v.tolist() == [-3.0, -2.0, -1.0] and sweeps == 1
    assert mdl.a.C[BACKUPS] == mdl.backups  # (its sweeps are not the model's backups)


def test_a_loop_known_only_by_hope_falls_to_the_floor_within_the_sweeps():
    # 0 -> 1 -> 0 under action 0 (return -1 each), action 1 of both untried: with optimism each is worth
    # v_opt; without, the loop is worth v_min = -100, reached after about 50 sweeps of two units each.
    mdl = model(states=2)
    observe(mdl, 0, 0, -1.0, 1)
    observe(mdl, 1, 0, -1.0, 0)
    assert mdl.a.V[:2].tolist() == [10.0, 10.0]
    q, v, sweeps = greedy(mdl)
    assert v.tolist() == [-100.0, -100.0] and 40 < sweeps < 60
    _, v_cut, cut = greedy(mdl, max_sweeps=5)
    assert cut == 5 and v_cut[0] > -100.0  # (a value still moving when the sweeps run out is left there)


def test_a_loop_at_a_gain_stops_at_the_ceiling():
    # 0 -> 0 under action 0 with return +1 and gamma 1 (a loop an aggregated model can hold), action 1 to the
    # end with 3: without a ceiling its value grows by 1 a sweep for ever; with none set, v_opt (10) bounds it.
    assert greedy_ceiling(10.0, 1e308 * 10) == 10.0 and greedy_ceiling(-5.0, 1e308 * 10) == 0.0
    assert greedy_ceiling(10.0, 4.0) == 4.0  # (the model's own ceiling where it has one)
    mdl = model(states=1)
    observe(mdl, 0, 0, 1.0, 0)
    observe(mdl, 0, 1, 3.0, -1)
    q, v, sweeps = greedy(mdl)
    assert q[0].tolist() == [10.0, 3.0] and sweeps <= 2


def test_decisions_the_plan_values_alike_are_told_apart_by_the_planned_values():
    mdl = model(m=3, states=2)
    # From state 0 each action leads to state 1, whose decisions are all untried: without optimism every one
    # is worth the floor (-100), alike; with it, -1 + 10, -3 + 10 and -2 + 10. The greedy action is 0.
    for a, r in ((0, -1.0), (1, -3.0), (2, -2.0)):
        observe(mdl, 0, a, r, 1)
    q, _, _ = greedy(mdl)
    assert q[0].tolist() == [-100.0] * 3 and mdl.a.Q[0].tolist() == [9.0, 7.0, 8.0]
    assert greedy_actions(mdl.a).tolist() == [0, 0]  # (state 1: all alike, all planned at v_opt: the first)
    # One of them known to end well is chosen over the hopes: (0, 2) -> the end with 4.
    observe(mdl, 0, 2, 4.0, -1)
    assert greedy_actions(mdl.a)[0] == 2 and mdl.a.Q[0].argmax() == 0


@pytest.mark.parametrize("name", ["avq", "tabular-ps"])
def test_predict_follows_the_plan_without_optimism_and_plans_again_after_learning(name):
    env = gym.make("avq/SlabMaze-v0", dims=2, layout_seed=2) if name == "avq" else gym.make("avq/GridMaze-v0")
    steps = 1500 if name == "avq" else 450
    agent = avq.make_agent(name, env, seed=3).learn(total_timesteps=steps)
    if name == "avq":
        obs = np.random.default_rng(0).random((400, 2)).astype(np.float32)
        rows = agent.cells(obs)
    else:
        obs = agent.states_.astype(np.float32)  # (one row per observation seen, in the rows' order)
        rows = np.arange(len(obs))
    actions, _ = agent.predict(obs, deterministic=True)
    floor = greedy_floor(agent.history_.lowest_return())
    assert floor == min(0.0, agent.episode_history()["return"].min()) > -np.inf
    assert np.array_equal(actions, greedy_actions(agent.model_.a, floor)[rows])
    # Somewhere the exploring agent's values would have chosen otherwise (towards what it has not tried).
    assert np.any(actions != agent.q_[rows].argmax(axis=1))
    # After more learning the greedy values are planned again from the changed model.
    before = greedy_actions(agent.model_.a, floor)
    agent.learn(total_timesteps=steps)
    if name == "avq":
        rows = agent.cells(obs)
    else:
        obs = agent.states_.astype(np.float32)
        rows = np.arange(len(obs))
    after = greedy_actions(agent.model_.a, greedy_floor(agent.history_.lowest_return()))
    assert len(after) > len(before) or np.any(after != before[: len(after)])  # (the model did change)
    assert np.array_equal(agent.predict(obs, deterministic=True)[0], after[rows])
