"""Every rule of SPEC §2-§5, each in a situation built by hand with the numbers written out.

The scripted environment plays back fixed observations, rewards and collisions
whatever the agent does, and logs the actions the agent took.
"""

import numpy as np
import pytest

from avq import AVQSarsa
from avq._random import RawStream
from avq.agents._td import decide, sarsa_lambda, sarsa_td_error, trace_update
from avq.agents.avq_sarsa import episode_end, kernels as core
from avq.rules import APPEND, CHI, KEEP, collision_rule, merge_profiles, similar_profiles

from conftest import ScriptedEnv

NO = False


def agent_for(episodes, **kw):
    params = dict(
        alpha=0.5,
        lam=0.7,
        gamma=1.0,
        epsilon=0.0,
        d_min=1.0,
        rho=0.0,
        chi=-4.0,
        q_init=0.0,
        merge_every=0,
        scale=1.0,
        seed=0,
    )
    params.update(kw)
    env = ScriptedEnv(episodes)
    return AVQSarsa(env, **params), env


# -- SPEC §3: growing ---------------------------------------------------------------------


def test_first_vector_is_the_first_observation_with_q_init():
    agent, env = agent_for([((1.5, -2.0), [((1.5, -2.0), -1, True, NO, NO)])], q_init=3.0)
    agent.learn(total_timesteps=0)
    agent.learn(total_episodes=1)
    assert agent.codebook_.tolist() == [[1.5, -2.0]]
    a = env.actions[0][0]
    # One terminal step: delta = -1 - 3 = -4; Q[0, a] = 3 + 0.5 * -4 = 1.
    expected = np.full(2, 3.0)
    expected[a] = 1.0
    assert agent.q_.tolist() == [expected.tolist()]


def test_collision_within_d_min_sets_chi_then_learns():
    # From (0, 0), a bump at (0.5, 0): ||y_0 - x|| = 0.5 <= d_min = 1, so Q[0, a] = chi = -4.
    # Then the transition is learned: a' is the other action (Q = 0 > -4), delta = -10 + 0 - (-4) = -6,
    # Q[0, a] = -4 + 0.5 * -6 = -7.
    agent, env = agent_for([((0, 0), [((0.5, 0), -10, NO, True, True)])])
    agent.learn(total_episodes=1)
    a = env.actions[0][0]
    assert agent.n_cells == 1
    q = np.zeros(2)
    q[a] = -7.0
    assert agent.q_.tolist() == [q.tolist()]
    assert agent.history_[0]["appends"] == 0


def test_collision_far_from_the_cell_appends_with_the_parents_profile():
    # Episode 1 teaches Q[0, a1] = 4.5: two steps in cell 0, R = -1 + 10 = 9, terminal, 0.5 * 9.
    # Episode 2 from (0, 0) bumps at (3, 0): 3 > d_min, so (3, 0) is appended as cell 1 with
    # Q[1] = Q[0] (inherited), then Q[1, a2] = chi = -4.
    ep1 = ((0, 0), [((0.2, 0), -1, NO, NO, NO), ((0.4, 0), 10, True, NO, NO)])
    ep2 = ((0, 0), [((3, 0), -10, NO, True, True)])
    agent, env = agent_for([ep1, ep2], q_init=0.0)
    agent.learn(total_episodes=1)
    a1 = env.actions[0][0]
    assert env.actions[0] == [a1, a1]  # one decision, repeated while the cell stays the same
    q0 = np.zeros(2)
    q0[a1] = 4.5
    assert agent.q_.tolist() == [q0.tolist()]
    agent.learn(total_episodes=1)
    a2 = env.actions[1][0]
    assert a2 == a1  # greedy: Q[0, a1] = 4.5 is the best
    assert agent.codebook_.tolist() == [[0, 0], [3, 0]]
    q1 = q0.copy()
    q1[a2] = -4.0
    assert agent.q_[1].tolist() == q1.tolist()
    # The transition (0, a2) -> 1: a' = the other action (0 > -4), delta = -10 + 0 - 4.5 = -14.5.
    expected_q0 = q0.copy()
    expected_q0[a2] = 4.5 + 0.5 * -14.5
    assert agent.q_[0].tolist() == expected_q0.tolist()
    assert agent.history_[1]["appends"] == 1


def test_no_append_within_d_min_of_an_existing_vector():
    # Cells at (0, 0) and (3, 0) (from a far bump). Then a bump from cell 0 lands at (2.5, 0):
    # 2.5 from y_0 (> d_min) but 0.5 from y_1 (<= d_min): no append, and no chi.
    ep1 = ((0, 0), [((3, 0), -10, NO, True, True)])
    ep2 = ((0, 0), [((2.5, 0), -10, NO, True, True)])
    agent, env = agent_for([ep1, ep2])
    agent.learn(total_episodes=2)
    assert agent.codebook_.tolist() == [[0, 0], [3, 0]]
    assert agent.history_[1]["appends"] == 0


def test_collision_rule_outcomes():
    assert collision_rule(0.5, 0.5, 1.0) == CHI
    assert collision_rule(1.0, 1.0, 1.0) == CHI  # <= d_min
    assert collision_rule(1.01, 1.01, 1.0) == APPEND
    assert collision_rule(2.5, 0.5, 1.0) == KEEP


def test_value_change_trigger_appends_inheriting_the_end_cell():
    # One step to (3, 0), truncated, reward -5: delta = -5 + Q[0, a'] - Q[0, a] = -5.
    ep = ((0, 0), [((3, 0), -5, NO, True, NO)])
    agent, env = agent_for([ep], value_trigger=4.0)
    agent.learn(total_episodes=1)
    a = env.actions[0][0]
    assert agent.codebook_.tolist() == [[0, 0], [3, 0]]
    q0 = np.zeros(2)
    q0[a] = -2.5
    assert agent.q_.tolist() == [q0.tolist(), q0.tolist()]  # cell 1 inherits Q[0] after the update


def test_value_change_trigger_needs_a_large_error_and_distance():
    ep = ((0, 0), [((3, 0), -5, NO, True, NO)])
    for kw in (dict(value_trigger=6.0), dict(value_trigger=4.0, d_min=3.0), dict(value_trigger=None)):
        agent, _ = agent_for([ep], **kw)
        agent.learn(total_episodes=1)
        assert agent.n_cells == 1, kw


def test_max_cells_refuses_appends():
    ep = ((0, 0), [((3, 0), -10, NO, True, True)])
    agent, _ = agent_for([ep], max_cells=1)
    agent.learn(total_episodes=1)
    assert agent.n_cells == 1
    assert agent.history_[0]["refused"] == 1


# -- SPEC §4: merging -----------------------------------------------------------------------


def _two_cell_agent(rho, merge_every=1):
    # Episode 1 appends (3, 0) with Q[1] = [0, 0] except chi = -4 at the bumping action;
    # Q[0, a] = 0 + 0.5 * (-10 + 0 - 0) = -5.  Profiles: Q[0] = (-5 at a, 0), Q[1] = (-4 at a, 0):
    # mean squared difference (1/2) * ((-5 + 4)^2 + 0) = 0.5.
    ep = ((0, 0), [((3, 0), -10, NO, True, True)])
    return agent_for([ep], rho=rho, merge_every=merge_every)


def test_mutual_pair_with_small_difference_merges_into_the_midpoint_and_mean():
    agent, env = _two_cell_agent(rho=0.6)
    agent.learn(total_episodes=1)
    a = env.actions[0][0]
    assert agent.codebook_.tolist() == [[1.5, 0]]
    q = np.zeros(2)
    q[a] = (-5 + -4) / 2
    assert agent.q_.tolist() == [q.tolist()]
    assert agent.history_[0]["merges"] == 1 and agent.history_[0]["n_cells"] == 1


def test_no_merge_when_the_difference_is_at_least_rho():
    agent, _ = _two_cell_agent(rho=0.5)  # msd = 0.5 is not < 0.5
    agent.learn(total_episodes=1)
    assert agent.n_cells == 2 and agent.history_[0]["merges"] == 0


def test_merge_runs_every_merge_every_episodes():
    # rho = 100 admits the pair whenever the pass runs; with merge_every = 2 it runs after episode 2 only.
    agent, _ = _two_cell_agent(rho=100.0, merge_every=2)
    agent.learn(total_episodes=1)
    assert agent.n_cells == 2
    agent.learn(total_episodes=1)
    assert agent.history_[1]["merges"] == 1


def merge_pass_on(vectors, q, rho, pairs="mutual"):
    """Run the training's merge pass (``_avq_core.merge_pass``) on cells set up by hand; return the
    codebook, the values and the number of merges."""
    p, m = q.shape
    cap = p + 2
    V, Q, E = np.zeros((cap, 2)), np.zeros((cap, m)), np.zeros((cap, m))
    V[:p], Q[:p] = vectors, q
    born = np.zeros((cap, 2 + m), dtype=np.int64)
    act, pc = np.zeros(cap + 1, dtype=np.int64), np.zeros((cap + 1, 2), dtype=np.int64)
    pc[0, 0] = -1
    P, IP, S = np.zeros(core.N_P), np.zeros(core.N_IP, dtype=np.int64), np.zeros(core.N_S, dtype=np.int64)
    P[core.FloatParam.RHO] = rho
    IP[core.IntParam.MERGE_PAIRS] = ("mutual", "mutual_ties", "nearest").index(pairs)
    S[core.SIZE], S[core.EPISODES] = p, 5
    n = episode_end.merge_pass(V, Q, E, born, act, pc, np.ones(2), P, IP, S)
    return V[: p - n], Q[: p - n], n


def test_no_merge_when_not_mutual():
    # Vectors 0 (0,0), 1 (2,0), 2 (3,0): 0's nearest is 1 but 1's is 2. Identical profiles:
    # only (1, 2) merges, into their midpoint (2.5, 0) at index 1.
    V, Q, n = merge_pass_on(np.array([[0.0, 0.0], [2.0, 0.0], [3.0, 0.0]]), np.zeros((3, 2)), 0.1)
    assert n == 1 and V.tolist() == [[0.0, 0.0], [2.5, 0.0]]


def test_similar_profiles_uses_the_mean_square_difference():
    q = np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 6.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.3]])
    # msd(0, 1) = 9 / 3 = 3; msd(2, 3) = 0.09 / 3 = 0.03
    assert not similar_profiles(q[0], q[1], 3.0) and similar_profiles(q[0], q[1], 3.01)
    assert similar_profiles(q[2], q[3], 0.031) and not similar_profiles(q[2], q[3], 0.03)
    # The same numbers decide the training's merge pass: two far-apart mutual pairs, rho 3 then 3.01.
    vectors = np.array([[0.0, 0.0], [1.0, 0.0], [10.0, 0.0], [11.0, 0.0]])
    V, Q, n = merge_pass_on(vectors, q, 3.0)
    assert n == 1 and Q.tolist() == [[1.0, 2.0, 3.0], [1.0, 2.0, 6.0], [0.0, 0.0, 0.15]]
    V, Q, n = merge_pass_on(vectors, q, 3.01)
    assert n == 2 and Q.tolist() == [[1.0, 2.0, 4.5], [0.0, 0.0, 0.15]]
    assert V.tolist() == [[0.5, 0.0], [10.5, 0.0]]


def test_merged_profile_averages_the_pair_and_keeps_the_rest():
    out = np.zeros(2)
    merge_profiles(np.array([1.0, 2.0]), np.array([3.0, 6.0]), out)
    assert out.tolist() == [2.0, 4.0]
    # In the merge pass: cells 0 and 2 are mutually nearest (cell 1 is far), so they merge at index 0.
    q = np.array([[1.0, 2.0], [9.0, 9.0], [3.0, 6.0]])
    V, Q, n = merge_pass_on(np.array([[0.0, 0.0], [20.0, 0.0], [1.0, 0.0]]), q, 100.0)
    assert n == 1 and Q.tolist() == [[2.0, 4.0], [9.0, 9.0]] and V.tolist() == [[0.5, 0.0], [20.0, 0.0]]


# -- SPEC §2, §5: acting and learning ---------------------------------------------------------


def test_two_transition_episode_by_hand():
    # alpha 0.5, lambda 0.7, gamma 0.9, chi -5, d_min 1.
    # T1 from cell 0 with action a0: (0.5, 0) r -1, then a bump at (3, 0) r -10.
    #    R = -1 + 0.9 * -10 = -10, k = 2. (3, 0) is 3 from y_0: appended as cell 1, Q[1] = [0, 0],
    #    Q[1, a0] = -5. a1 = the other action. delta = -10 + 0.81 * 0 - 0 = -10.
    #    E[0, a0] = 1; Q[0, a0] = -5; E *= 0.81 * 0.7 = 0.567.
    # T2 from cell 1 with a1: (4, 0) r +10, terminal. delta = 10 - 0 = 10. E[1, a1] = 1.
    #    Q[1, a1] = 5; Q[0, a0] = -5 + 0.5 * 10 * 0.567 = -2.165.
    ep = ((0, 0), [((0.5, 0), -1, NO, NO, NO), ((3, 0), -10, NO, NO, True), ((4, 0), 10, True, NO, NO)])
    agent, env = agent_for([ep], gamma=0.9, chi=-5.0)
    agent.learn(total_episodes=1)
    a0, a0_again, a1 = env.actions[0]
    assert a0_again == a0 and a1 == 1 - a0
    q = np.zeros((2, 2))
    q[0, a0] = -5 + 0.5 * 10 * (0.9**2 * 0.7)
    q[1, a0] = -5.0
    q[1, a1] = 5.0
    assert np.allclose(agent.q_, q, rtol=0, atol=1e-12)
    assert q[0, a0] == pytest.approx(-2.165)
    assert agent.history_[0]["decisions"] == 2


def test_truncation_bootstraps_and_termination_does_not():
    # q_init 2. One step r -1. Truncated: delta = -1 + 2 - 2 = -1 -> Q = 1.5.
    # Terminated: delta = -1 - 2 = -3 -> Q = 0.5.
    for terminated, expected in ((False, 1.5), (True, 0.5)):
        ep = ((0, 0), [((0.3, 0), -1, terminated, not terminated, NO)])
        agent, env = agent_for([ep], q_init=2.0)
        agent.learn(total_episodes=1)
        a = env.actions[0][0]
        assert agent.q_[0, a] == expected
        assert agent.q_[0, 1 - a] == 2.0


def test_traces_are_cleared_at_every_episode_start():
    # Episode 1 ends with E[0, a] = 0.7 (terminal update). Episode 2 is a single terminal step with the
    # other action forced by values: only that entry may change.
    ep = ((0, 0), [((0.1, 0), 10, True, NO, NO)])
    agent, env = agent_for([ep])
    agent.learn(total_episodes=1)
    a = env.actions[0][0]
    assert agent.q_[0, a] == 5.0
    agent.learn(total_episodes=1)
    # Greedy picks a again (5 > 0): delta = 10 - 5 = 5, Q = 7.5; a stale trace would have added more.
    assert env.actions[1][0] == a and agent.q_[0, a] == 7.5


def test_sarsa_lambda_update_replacing_and_accumulating():
    for replacing, q_00, e_00 in ((True, 1.0, 0.5), (False, 1.5, 0.75)):
        q = np.zeros((2, 2))
        e = np.array([[0.5, 0.0], [0.0, 0.2]])
        trace_update(q, e, np.array([0, 1]), 2, 0, 0, 2.0, 0.5, 0.5, replacing)
        assert q.tolist() == [[q_00, 0.0], [0.0, 0.2]] and e.tolist() == [[e_00, 0.0], [0.0, 0.1]]


def test_sarsa_lambda_touches_the_active_rows_and_adds_the_updated_one():
    # Active list: row 1 only (act[0] = 1). Updating (0, 0) adds row 0; row 2 (a stale trace not in the
    # list, which training never leaves behind) is not touched.
    q = np.zeros((3, 2))
    e = np.array([[0.0, 0.0], [0.0, 0.2], [1.0, 1.0]])
    act = np.array([1, 1, 0, 0])
    sarsa_lambda(q, e, act, 0, 0, 2.0, 0.5, 0.5, True)
    assert act[:3].tolist() == [2, 1, 0]
    assert q.tolist() == [[1.0, 0.0], [0.0, 0.2], [0.0, 0.0]]
    assert e.tolist() == [[0.5, 0.0], [0.0, 0.1], [1.0, 1.0]]


def test_td_error():
    assert sarsa_td_error(q_tm1=1.0, r_t=-2.0, discount_t=0.5, q_t=4.0, terminal=False) == -1.0
    assert sarsa_td_error(q_tm1=1.0, r_t=-2.0, discount_t=0.5, q_t=4.0, terminal=True) == -3.0


def test_epsilon_greedy_breaks_ties_at_random_and_explores():
    draws = RawStream(np.random.default_rng(0))

    def pick(q, eps):
        draws.reserve()
        return int(decide(draws.src, np.asarray(q)[None, :], 0, eps))

    q = [1.0, 3.0, 3.0, 0.0]
    picks = [pick(q, 0.0) for _ in range(400)]
    assert set(picks) == {1, 2} and 150 < picks.count(1) < 250
    picks = [pick(q, 1.0) for _ in range(400)]
    assert set(picks) == {0, 1, 2, 3}
    assert all(pick([0.0, 1.0], 0.0) == 1 for _ in range(20))


def test_epsilon_greedy_draws_what_the_generator_would():
    # u < epsilon: a random action is integers(0, m); else the greedy one, ties by integers(0, ties).
    draws, ref = RawStream(np.random.default_rng(5)), np.random.default_rng(5)
    q = np.array([[1.0, 3.0, 3.0, 0.0]])
    for _ in range(300):
        draws.reserve()
        got = int(decide(draws.src, q, 0, 0.3))
        want = int(ref.integers(0, 4)) if ref.random() < 0.3 else (1, 2)[int(ref.integers(0, 2))]
        assert got == want
    draws.sync()
    assert draws.rng.bit_generator.state == ref.bit_generator.state


def test_a_decision_is_repeated_until_the_cell_changes():
    # Cells at (0,0) and (10,0) exist after episode 1. Episode 2: three steps inside cell 0, then into
    # cell 1, one more step there and the goal: exactly two decisions.
    ep1 = ((0, 0), [((10, 0), -10, NO, True, True)])
    ep2 = (
        (0, 0),
        [
            ((1, 0), -1, NO, NO, NO),
            ((2, 0), -1, NO, NO, NO),
            ((3, 0), -1, NO, NO, NO),
            ((6, 0), -1, NO, NO, NO),
            ((7, 0), -1, NO, NO, NO),
            ((8, 0), 10, True, NO, NO),
        ],
    )
    agent, env = agent_for([ep1, ep2], epsilon=0.3, seed=3)
    agent.learn(total_episodes=2)
    acts = env.actions[1]
    assert len(set(acts[:4])) == 1 and len(set(acts[4:])) == 1
    assert agent.history_[1]["decisions"] == 2


# -- reward-jump trigger (for tasks without collisions) ----------------------------------------


def test_reward_jump_appends_the_new_observation_inheriting_the_current_cell():
    # Steps: (0.5, 0) r -1, (3, 0) r -7 (a jump of 6 >= 5, no collision), then terminal at (3.2, 0) r 0.
    # The jump appends (3, 0) as cell 1 with Q[1] = Q[0] = [0, 0]: the cell changes, so transition 1
    # (R = -1 - 7 = -8, a' = random tie in cell 1) ends there: delta = -8 + 0 - 0, Q[0, a0] = -4.
    # Transition 2 from cell 1: terminal, R = 0: delta = 0 - 0 = 0.
    ep = ((0, 0), [((0.5, 0), -1, NO, NO, NO), ((3, 0), -7, NO, NO, NO), ((3.2, 0), 0, True, NO, NO)])
    agent, env = agent_for([ep], reward_trigger=5.0)
    agent.learn(total_episodes=1)
    a0 = env.actions[0][0]
    assert env.actions[0][1] == a0
    assert agent.codebook_.tolist() == [[0, 0], [3, 0]]
    q = np.zeros((2, 2))
    q[0, a0] = -4.0
    assert agent.q_.tolist() == q.tolist()
    assert agent.history_[0]["decisions"] == 2


def test_reward_jump_below_threshold_within_d_min_or_on_a_collision_does_not_append():
    base = [((0.5, 0), -1, NO, NO, NO), ((3, 0), -7, NO, NO, NO), ((3.2, 0), -7, True, NO, NO)]
    for kw in (dict(reward_trigger=6.5), dict(reward_trigger=5.0, d_min=3.5)):
        agent, _ = agent_for([((0, 0), base)], **kw)
        agent.learn(total_episodes=1)
        assert agent.n_cells == 1, kw
    # The first step of an episode has no previous reward to compare with.
    agent, _ = agent_for([((0, 0), [((3, 0), -50, NO, NO, NO), ((3.1, 0), -50, True, NO, NO)])], reward_trigger=1.0)
    agent.learn(total_episodes=1)
    assert agent.n_cells == 1
    # A collision is handled by the collision rule alone (chi within d_min), not by the reward trigger.
    agent, _ = agent_for(
        [((0, 0), [((0.5, 0), -1, NO, NO, NO), ((0.6, 0), -10, NO, True, True)])], reward_trigger=1.0, d_min=1.0
    )
    agent.learn(total_episodes=1)
    assert agent.n_cells == 1


def test_merge_age_keeps_young_cells_apart():
    # The two-cell situation of the merge tests (msd 0.5 < rho 0.6), with merge_age 1: cell 1 was created
    # in episode 1, so after episode 1 it is 0 episodes old and may not merge.
    agent, _ = _two_cell_agent(rho=100.0)
    agent.merge_age = 1
    agent.learn(total_episodes=1)
    assert agent.n_cells == 2 and agent.history_[0]["merges"] == 0
    agent.learn(total_episodes=1)  # now 1 complete episode old
    assert agent.n_cells == 1 and agent.history_[1]["merges"] == 1


@pytest.mark.parametrize(
    ("q1", "same_action_guard", "merged"),
    [
        ([-1.0, -1.2], True, True),  # both prefer action 0: the guard lets them merge
        ([-1.2, -1.0], True, False),  # cell 0 prefers 0, cell 1 prefers 1: the guard keeps them apart
        ([-1.2, -1.0], False, True),  # the paper merges on the profile difference alone
    ],
)
def test_merge_same_action_guard(q1, same_action_guard, merged):
    from avq.agents.avq_sarsa import episode_end

    ep = ((0, 0), [((3, 0), -10, NO, True, True)])
    agent, _ = agent_for([ep], rho=100.0, merge_every=0, merge_same_action=same_action_guard)
    agent.learn(total_episodes=1)
    assert agent.n_cells == 2
    agent._Q[0, :2] = [-1.0, -1.1]  # greedy action 0
    agent._Q[1, :2] = q1  # msd with row 0 is at most 0.02 < rho
    n = episode_end.merge_pass(*agent._state()[:10])
    assert (n == 1) == merged and agent.n_cells == (1 if merged else 2)
    if merged:
        assert np.allclose(agent.q_[0], (np.array([-1.0, -1.1]) + np.array(q1)) / 2)


# -- beyond the paper: collision split and merging on ties -------------------------------------


@pytest.mark.parametrize("split", [False, True])
def test_collision_split_keeps_a_greedy_action_for_the_rest_of_the_cell(split):
    # Episode 1 teaches Q[0, a1] = 4.5 (two steps in cell 0, R = 9, terminal, alpha 0.5).
    # Episode 2: greedy a1 bumps at (0.5, 0), within d_min of y_0.
    # Paper: Q[0, a1] = chi = -4, then delta = -10 + Q[0, a2] - (-4) = -6, Q[0, a1] = -7; one cell.
    # Split: (0.5, 0) becomes cell 1 = copy of cell 0 with Q[1, a1] = chi; then a' = a2 at cell 1
    # (0 > -4), delta = -10 + 0 - 4.5 = -14.5 and Q[0, a1] = 4.5 - 7.25 = -2.75, still above Q[1, a1].
    ep1 = ((0, 0), [((0.2, 0), -1, NO, NO, NO), ((0.4, 0), 10, True, NO, NO)])
    ep2 = ((0, 0), [((0.5, 0), -10, NO, True, True)])
    agent, env = agent_for([ep1, ep2], collision_split=split)
    agent.learn(total_episodes=2)
    a1 = env.actions[0][0]
    assert env.actions[1][0] == a1  # greedy
    if split:
        assert agent.codebook_.tolist() == [[0, 0], [0.5, 0]]
        assert agent.q_[0, a1] == -2.75 and agent.q_[1, a1] == -4.0
        assert agent.q_[1, 1 - a1] == agent.q_[0, 1 - a1] == 0.0
        assert agent.history_[1]["appends"] == 1
    else:
        assert agent.codebook_.tolist() == [[0, 0]] and agent.q_[0, a1] == -7.0


def test_collision_split_leaves_the_vector_itself_to_the_paper_rule():
    # A bump exactly at y_0 (distance 0) cannot be split off: chi for the cell, as in the paper.
    ep1 = ((0, 0), [((0.2, 0), -1, NO, NO, NO), ((0.4, 0), 10, True, NO, NO)])
    ep2 = ((0, 0), [((0, 0), -10, NO, True, True)])
    agent, env = agent_for([ep1, ep2], collision_split=True)
    agent.learn(total_episodes=2)
    assert agent.n_cells == 1 and agent.q_[0, env.actions[0][0]] == -7.0


def test_merge_pairs_mutual_ties_pairs_a_tied_nearest_by_lowest_index():
    from avq.agents.avq_sarsa import episode_end, kernels as core
    from avq.quantizer import mutual_nearest_pairs_kernel

    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    one = np.ones(2)
    # Vector 1 is equally near 0 and 2: the paper's strict rule finds no pair; the tie rule pairs (0, 1).
    assert mutual_nearest_pairs_kernel(line, 3, one).tolist() == []
    assert mutual_nearest_pairs_kernel(line, 3, one, False).tolist() == [[0, 1]]
    for rule, merged in (("mutual", 0), ("mutual_ties", 1)):
        agent, _ = agent_for([((0, 0), [((0, 0), -1, True, NO, NO)])], rho=100.0, merge_pairs=rule)
        agent.learn(total_episodes=1)
        agent._ensure_capacity(3)
        agent._V[:3], agent._Q[:3] = line, 0.0
        agent._S[core.SIZE] = 3
        agent._S[core.GEOM] += 1
        assert episode_end.merge_pass(*agent._state()[:10]) == merged
        if merged:
            assert agent.codebook_.tolist() == [[0.5, 0.0], [2.0, 0.0]]


def test_merge_pairs_nearest_pairs_closest_first_mutual_or_not():
    from avq.quantizer import nearest_pairs_kernel

    # 0 (0,0) and 1 (1,0) are 1 apart and pair first. 2 (2.5,0)'s nearest is 1 (1.5), already taken;
    # 3 (4.5,0)'s nearest is 2 (2.0), free: pair (2, 3), although 2's own nearest is 1.
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [2.5, 0.0], [4.5, 0.0]])
    assert nearest_pairs_kernel(pts, 4, np.ones(2)).tolist() == [[0, 1], [2, 3]]
    # The paper's rule pairs only (0, 1): 2's nearest (1) is not mutual.
    from avq.quantizer import mutual_nearest_pairs_kernel

    assert mutual_nearest_pairs_kernel(pts, 4, np.ones(2)).tolist() == [[0, 1]]
    with pytest.raises(ValueError, match="merge_pairs must be one of"):
        agent_for([((0, 0), [((0, 0), -1, True, NO, NO)])], merge_pairs="closest")


def _cycle_agent(return_obs, **kw):
    # Episode 1 makes two cells: a bump at (5, 0), far from y_0 = (0, 0), appends it (then truncation).
    # By hand: cell 0 prefers action 0, cell 1 action 1. Episode 2 (epsilon 0, all greedy): from cell 0
    # action 0 reaches (5, 0) in cell 1, whose action 1 returns to cell 0 at return_obs; then the
    # episode runs out at (0.3, 0).
    ep1 = ((0, 0), [((5, 0), -1, NO, True, True)])
    ep2 = ((0.4, 0), [((5, 0), -1, NO, NO, NO), (return_obs, -1, NO, NO, NO), ((0.3, 0), -1, NO, True, NO)])
    agent, env = agent_for([ep1, ep2], **kw)
    agent.learn(total_episodes=1)
    assert agent.codebook_.tolist() == [[0, 0], [5, 0]]
    agent._Q[0, :2] = (1.0, 0.0)
    agent._Q[1, :2] = (0.0, 1.0)
    agent.learn(total_episodes=1)
    assert env.actions[1][:2] == [0, 1]  # both decisions greedy
    return agent


@pytest.mark.parametrize("cycle_split", [False, True])
def test_cycle_split_splits_off_the_return_into_a_cell_left_by_two_greedy_decisions(cycle_split):
    agent = _cycle_agent((0.3, 0), cycle_split=cycle_split)
    # Transition 0 -> 1: delta = -1 + Q[1, 1] - Q[0, 0] = -1, Q[0, 0] = 0.5.
    # Transition 1 -> 0 at (0.3, 0): delta = -1 + Q[0, 0] - Q[1, 1] = -1.5; E[1, 1] = 1, E[0, 0] = 0.7:
    # Q[1, 1] = 1 - 0.75 = 0.25, Q[0, 0] = 0.5 - 0.525 = -0.025. A cycle 0 -> 1 -> 0 of greedy decisions:
    # the split appends (0.3, 0) as a copy of cell 0 (its profile after that update).
    if not cycle_split:
        assert agent.n_cells == 2 and agent.history_[1]["appends"] == 0
        return
    assert agent.codebook_.tolist() == [[0, 0], [5, 0], [0.3, 0]]
    assert agent.history_[1]["appends"] == 1
    # The last transition (2, a=0) -> truncation at (0.3, 0), still cell 2: a' = greedy of Q[2] = (-0.025, 0)
    # is 1. delta = -1 + Q[2, 1] - Q[2, 0] = -0.975 with E[2, 0] = 1, E[1, 1] = 0.7, E[0, 0] = 0.49.
    delta = -1 + 0.0 - (-0.025)
    assert np.allclose(agent.q_[2, :2], (-0.025 + 0.5 * delta, 0.0))
    assert np.allclose(agent.q_[0, :2], (-0.025 + 0.5 * delta * 0.49, 0.0))
    assert np.allclose(agent.q_[1, :2], (0.0, 0.25 + 0.5 * delta * 0.7))


def test_cycle_split_leaves_the_vector_itself_and_respects_max_cells():
    # A return exactly onto y_0 cannot be split off.
    assert _cycle_agent((0, 0), cycle_split=True).n_cells == 2
    # At max_cells the split is refused and counted.
    agent = _cycle_agent((0.3, 0), cycle_split=True, max_cells=2)
    assert agent.n_cells == 2 and agent.history_[1]["refused"] == 1


def test_cycle_split_needs_greedy_decisions():
    # epsilon 1: the decisions are random; whenever the walk 0 -> 1 -> 0 was not greedy twice, no split.
    seen = set()
    for seed in range(12):
        ep1 = ((0, 0), [((5, 0), -1, NO, True, True)])
        ep2 = ((0.4, 0), [((5, 0), -1, NO, NO, NO), ((0.3, 0), -1, NO, NO, NO), ((0.3, 0), -1, NO, True, NO)])
        agent, env = agent_for([ep1, ep2], cycle_split=True, epsilon=1.0, seed=seed)
        agent.learn(total_episodes=1)
        agent._Q[0, :2] = (1.0, 0.0)
        agent._Q[1, :2] = (0.0, 1.0)
        agent.learn(total_episodes=1)
        greedy_twice = env.actions[1][:2] == [0, 1]
        assert agent.n_cells == (3 if greedy_twice else 2), (seed, env.actions[1])
        seen.add(greedy_twice)
    assert seen == {True, False}  # both cases occurred


def test_adapt_rate_moves_the_cell_vector_toward_each_observation_but_not_on_collisions():
    # y_0 = (0, 0); rate 0.5: (0.2, 0) moves it to 0.1, (0.4, 0) to 0.25; the bump at (1, 0) (within
    # d_min 1 of y_0, chi for the cell) leaves it; the terminal (0.05, 0.5) moves it to (0.15, 0.25).
    steps = [
        ((0.2, 0), -1, NO, NO, NO),
        ((0.4, 0), -1, NO, NO, NO),
        ((1.0, 0), -1, NO, NO, True),
        ((0.05, 0.5), 10, True, NO, NO),
    ]
    agent, _ = agent_for([((0, 0), steps)], adapt_rate=0.5)
    agent.learn(total_episodes=1)
    assert np.allclose(agent.codebook_, [[0.15, 0.25]])
    still, _ = agent_for([((0, 0), steps)])
    still.learn(total_episodes=1)
    assert still.codebook_.tolist() == [[0, 0]]
    with pytest.raises(ValueError, match="adapt_rate"):
        agent_for([((0, 0), steps)], adapt_rate=1.0)


def test_prune_after_removes_cells_without_decisions_for_that_many_episodes():
    # Episode 1 (from (0, 0)) bumps at (5, 0), far from y_0: cell 1 appended; the episode is truncated
    # there, so a decision is learned into cell 1 (last decision: episode 1). Episodes 2 and 3 start
    # at (0.2, 0) and terminate at (0.4, 0) in cell 0: cell 1 sees no decision.
    ep1 = ((0, 0), [((5, 0), -1, NO, True, True)])
    ep2 = ((0.2, 0), [((0.4, 0), 10, True, NO, NO)])
    for prune_after, cells in ((0, [2, 2, 2]), (2, [2, 2, 1]), (1, [2, 1, 1])):
        agent, _ = agent_for([ep1, ep2, ep2], prune_after=prune_after)
        counts = []
        for _ in range(3):
            agent.learn(total_episodes=1)
            counts.append(agent.n_cells)
        assert counts == cells, prune_after
        assert agent.codebook_[0].tolist() == [0, 0]
    # The survivors keep their values and order: prune cell 0 instead by starting far away.
    ep_far = ((5, 0), [((5.2, 0), 10, True, NO, NO)])
    agent, _ = agent_for([ep1, ep_far, ep_far], prune_after=1)
    agent.learn(total_episodes=1)
    q1 = agent.q_[1].copy()
    agent.learn(total_episodes=1)
    assert agent.codebook_.tolist() == [[5, 0]] and agent.n_cells == 1
    assert agent.q_[0, 1 - agent.env.unwrapped.actions[1][0]] == q1[1 - agent.env.unwrapped.actions[1][0]]
    with pytest.raises(ValueError, match="prune_after"):
        agent_for([ep1], prune_after=-1)


def test_explore_bonus_decides_on_values_plus_bonus_per_decision_count():
    from avq.agents.avq_sarsa import kernels as core

    # By hand: Q[0] = (1, 0.5), counts (1, 0), bonus 2: 1 + 2/sqrt(2) = 2.414 < 0.5 + 2/sqrt(1) = 2.5.
    Q = np.array([[1.0, 0.5]])
    born = np.array([[0, 0, 1, 0]])
    P = np.zeros(core.N_P)
    P[core.FloatParam.EXPLORE_BONUS] = 2.0
    out = np.empty((1, 2))
    core.bonus_values(Q, born, P, 0, out)
    assert np.allclose(out, [[1 + 2 / np.sqrt(2), 2.5]])
    # One-step episodes with reward 0 and q_init 0: Q stays 0, so only the counts decide. With the bonus,
    # after a tie (broken at random) the next decision takes the other action: the actions of episodes
    # 2k and 2k+1 always differ, and the counts stay even. Without it, ties are broken at random.
    ep = ((0, 0), [((0.1, 0), 0.0, True, NO, NO)])
    agent, env = agent_for([ep], explore_bonus=1.0)
    agent.learn(total_episodes=40)
    acts = [a[0] for a in env.actions]
    assert all(acts[k] != acts[k + 1] for k in range(0, 40, 2))
    assert agent._born[0, 2:].tolist() == [20, 20] and agent.q_.tolist() == [[0.0, 0.0]]
    plain, env = agent_for([ep])
    plain.learn(total_episodes=40)
    acts = [a[0] for a in env.actions]
    assert any(acts[k] == acts[k + 1] for k in range(0, 40, 2))
    with pytest.raises(ValueError, match="explore_bonus"):
        agent_for([ep], explore_bonus=-1.0)


@pytest.mark.parametrize("make_room, refused", [(False, 2), (True, 0), (True, 1), (True, 2)])
def test_make_room_merges_as_many_more_same_action_pairs_as_growth_was_refused(make_room, refused):
    from avq.agents.avq_sarsa import episode_end, kernels as core

    # Three nearest pairs, far apart: (0, 1), (2, 3), (4, 5), none similar enough for rho = 1.
    # Same greedy action in (0, 1) (difference 9) and (2, 3) (difference 4); not in (4, 5).
    V = np.array([[0, 0], [1, 0], [10, 0], [11, 0], [20, 0], [21, 0], [0, 0], [0, 0]], float)
    Q = np.array([[5, 0], [2, 0], [7, 1], [5, 1], [1, 0], [0, 1], [0, 0], [0, 0]], float)
    cap, m = 8, 2
    E = np.zeros((cap, m))
    born = np.zeros((cap, 2 + m), np.int64)
    act = np.zeros(cap + 1, np.int64)
    pc = np.zeros((cap + 1, 2), np.int64)
    pc[0, 0] = -1
    P = np.zeros(core.N_P)
    P[core.FloatParam.RHO] = 1.0
    IP = np.zeros(core.N_IP, np.int64)
    IP[core.IntParam.MERGE_PAIRS] = 2  # "nearest"
    IP[core.IntParam.MAKE_ROOM] = make_room
    S = np.zeros(core.N_S, np.int64)
    S[core.SIZE] = 6
    S[core.REFUSED] = refused
    n = episode_end.merge_pass(V, Q, E, born, act, pc, np.ones(2), P, IP, S)
    expected = {(False, 2): 0, (True, 0): 0, (True, 1): 1, (True, 2): 2}[(make_room, refused)]
    assert n == expected and S[core.SIZE] == 6 - n
    if n == 1:  # the most similar same-action pair, (2, 3), merged into slot 2
        assert V[:5].tolist() == [[0, 0], [1, 0], [10.5, 0], [20, 0], [21, 0]]
        assert Q[2].tolist() == [6, 1]
    if n == 2:  # then (0, 1); (4, 5) never: their greedy actions differ
        assert V[:4].tolist() == [[0.5, 0], [10.5, 0], [20, 0], [21, 0]]
