"""Planning over a learned model: the model and prioritized sweeping (agents/plan/model.py), tabular-ps, and
avq-plan's rules (agents/plan/kernels.py, agents/plan/memory.py), each set up by hand with the numbers written
out."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq.agents.plan import kernels as core, memory, model as _model, tabular
from avq.agents.plan.model import BACKUPS, HEAP_N, KNOWN, Model
from avq.agents.plan.state import MEM_POS, N_F, SIZE, SLOPE_N, SLOPE_SUM, PlanParam


def model(m=2, v_opt=10.0, v_min=-100.0, known=1, tol=1e-9, states=3):
    mdl = Model(m, v_opt, v_min, known, tol)
    for _ in range(states):
        mdl.add_state()
    return mdl


def observe(mdl, s, a, r, disc, s2, budget=1000):
    mdl.reserve(edges=1)
    return tabular.observe(mdl.a, s, a, r, disc, s2, budget)


# -- the model ----------------------------------------------------------------------------------------


def test_an_untried_pair_is_worth_v_opt_and_a_tried_one_its_statistics():
    mdl = model()
    assert mdl.a.Q[:3].tolist() == [[10.0, 10.0]] * 3 and mdl.a.V[:3].tolist() == [10.0] * 3
    # (0, 1) -> terminal with return 4: Q = 4, and action 0, untried, keeps V(0) at 10.
    observe(mdl, 0, 1, 4.0, 1.0, -1)
    assert mdl.a.Q[0].tolist() == [10.0, 4.0] and mdl.a.V[0] == 10.0
    # (0, 0) -> state 1 (untried, worth 10), return -1, discount 0.5: Q = -1 + 0.5 * 10 = 4.
    observe(mdl, 0, 0, -1.0, 0.5, 1)
    assert mdl.a.Q[0].tolist() == [4.0, 4.0] and mdl.a.V[0] == 4.0


def test_a_stochastic_pair_is_the_mean_over_its_successors():
    mdl = model(states=3)
    # Make V(1) = 2 and V(2) = -6 by terminal transitions of both actions.
    for s, r in ((1, 2.0), (2, -6.0)):
        for a in (0, 1):
            observe(mdl, s, a, r, 1.0, -1)
    assert mdl.a.V[1] == 2.0 and mdl.a.V[2] == -6.0
    # (0, 0): three times to 1 with return -1, once to 2 with return -3 (discount 1).
    for s2, r in ((1, -1.0), (1, -1.0), (2, -3.0), (1, -1.0)):
        observe(mdl, 0, 0, r, 1.0, s2)
    # Q = (sum R + 3 * V(1) + 1 * V(2)) / 4 = (-6 + 6 - 6) / 4 = -1.5
    assert mdl.a.Q[0, 0] == pytest.approx(-1.5)


def test_an_smdp_transition_discounts_its_successor_by_gamma_to_the_k():
    mdl = model(states=2)
    observe(mdl, 1, 0, 8.0, 1.0, -1)
    observe(mdl, 1, 1, 8.0, 1.0, -1)
    # Three steps of reward -1 with gamma 0.9: R = -1 - 0.9 - 0.81 = -2.71, discount 0.729.
    observe(mdl, 0, 0, -2.71, 0.9**3, 1)
    assert mdl.a.Q[0, 0] == pytest.approx(-2.71 + 0.729 * 8.0)


def test_values_are_floored_at_v_min_so_a_loop_without_exit_converges():
    # (0, a) -> 0 with return -1 for both actions, gamma 1: without a floor V(0) would fall for ever.
    mdl = model(states=1, v_min=-20.0)
    observe(mdl, 0, 0, -1.0, 1.0, 0, budget=0)
    observe(mdl, 0, 1, -1.0, 1.0, 0, budget=10_000)
    assert mdl.a.V[0] == -20.0 and mdl.queued == 0
    assert mdl.backups < 100  # about 30 backups of one unit each, then the floor holds


def test_prioritized_sweeping_carries_a_change_back_along_a_chain_within_the_budget():
    # A chain 0 -> 1 -> 2 -> 3 -> terminal (action 0, return -1), each tried once while the next was
    # unknown (v_opt 10); action 1 is made worse than everything (a terminal return of -50).
    mdl = model(states=4)
    for s in range(4):
        observe(mdl, s, 1, -50.0, 1.0, -1, budget=0)
    for s in range(3):
        observe(mdl, s, 0, -1.0, 1.0, s + 1, budget=0)
    # With no budget beyond the pair's own state, values upstream are stale: V(0) is 9 where the model says
    # 8 (V(1) fell to 9 after V(0) was computed); states 0 and 1 wait in the queue with priority 1.
    assert mdl.a.V[:4].tolist() == [9.0, 9.0, 9.0, 10.0] and mdl.queued == 2
    # The last link: 3 -> terminal with return -1: V(3) falls by 11 and queues state 2 with priority 11.
    observe(mdl, 3, 0, -1.0, 1.0, -1, budget=0)
    assert mdl.a.V[:4].tolist() == [9.0, 9.0, 9.0, -1.0] and mdl.queued == 3
    # Largest change first: state 2 (V = -2), which raises state 1's priority to 12; then 1 and 0.
    assert _model.sweep(mdl.a, 1) == 1 and mdl.a.V[:4].tolist() == [9.0, 9.0, -2.0, -1.0] and mdl.queued == 2
    assert _model.sweep(mdl.a, 10) == 2 and mdl.a.V[:4].tolist() == [-4.0, -3.0, -2.0, -1.0]
    assert mdl.queued == 0


def test_the_queue_backs_up_the_largest_change_first():
    mdl = model(states=3)
    a = mdl.a
    for s, p in ((0, 1.0), (1, 5.0), (2, 3.0)):
        _model.push(a.heap, a.hpos, a.prio, a.C, s, p)
    _model.push(a.heap, a.hpos, a.prio, a.C, 0, 7.0)  # raised
    _model.push(a.heap, a.hpos, a.prio, a.C, 1, 2.0)  # not lowered
    order = [_model.pop(a.heap, a.hpos, a.prio, a.C) for _ in range(3)]
    assert order == [0, 1, 2] and a.C[HEAP_N] == 0 and (a.hpos[:3] == -1).all()


def test_removing_a_transition_undoes_adding_it():
    mdl = model(states=3)
    observe(mdl, 0, 0, -1.0, 1.0, 1)
    before = {k: v.copy() for k, v in mdl.state_dict().items()}
    observe(mdl, 0, 0, -3.0, 0.5, 2)
    _model.record(mdl.a, 0, 0, -3.0, 0.5, 2, -1)
    _model.settle(mdl.a, 0, 100)
    after = mdl.state_dict()
    for name in ("m_cnt", "m_rsum", "m_Q", "m_V"):
        assert np.array_equal(before[name], after[name]), name
    assert after["m_e_n"].tolist() == [1, 0]  # the edge to 2 stays, empty


def test_a_pair_is_known_after_known_after_transitions():
    mdl = model(known=2)
    observe(mdl, 0, 0, -1.0, 1.0, -1)
    assert mdl.a.Q[0, 0] == 10.0
    observe(mdl, 0, 0, -3.0, 1.0, -1)
    assert mdl.a.Q[0, 0] == -2.0 and mdl.a.C[KNOWN] == 2


# -- tabular-ps ---------------------------------------------------------------------------------------


def corridor(**kw):
    return gym.make("avq/GridMaze-v0", layout=["#######", "#S...G#", "#######"], **kw)


def test_tabular_ps_learns_the_corridor_in_one_pass_of_trying_each_action():
    agent = avq.make_agent("tabular-ps", corridor(start="fixed"), seed=0).learn(total_episodes=30)
    # Every state's greedy action is East, valued exactly by the model: 10 - (steps to the goal - 1).
    assert [int(a) for a in agent.q_.argmax(axis=1)[:4]] == [1, 1, 1, 1]
    q = {tuple(int(v) for v in s): agent.q_[k, 1] for k, s in enumerate(agent.states_)}
    assert [q[(x, 1)] for x in (1, 2, 3, 4)] == [7.0, 8.0, 9.0, 10.0]
    assert agent.queued_ == 0
    assert avq.evaluate_maze(agent, corridor())["success_rate"] == 1.0
    # Optimism tries each of the 4 actions of the 4 states at most a few times: later episodes are shortest.
    assert agent.episode_history()["steps"][-5:].tolist() == [4] * 5


@pytest.mark.parametrize("name", ["tabular-ps", "avq-plan"])
@pytest.mark.parametrize("env_kw", [dict(), dict(slip=0.1)])
def test_fused_and_generic_paths_give_identical_results(name, env_kw):
    out = []
    for fused in (True, False):
        agent = avq.make_agent(name, gym.make("avq/GridMaze-v0", **env_kw), seed=4, fused=fused)
        agent.learn(total_episodes=40).learn(total_timesteps=333)
        out.append((agent.q_, agent.episode_history()["steps"], agent.num_timesteps, agent.backups_))
    (q1, h1, n1, b1), (q2, h2, n2, b2) = out
    assert np.array_equal(q1, q2) and np.array_equal(h1, h2) and n1 == n2 and b1 == b2


def test_avq_plan_fused_and_generic_on_the_robot():
    out = []
    for fused in (True, False):
        agent = avq.make_agent("avq-plan", gym.make("avq/RobotMaze-v0", move=0.5), seed=2, fused=fused)
        agent.learn(total_episodes=8)
        out.append((agent.codebook_, agent.q_, agent.episode_history()["steps"]))
    for x, y in zip(*out):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("name", ["tabular-ps", "avq-plan"])
def test_resume_after_loading_is_exact(tmp_path, name):
    whole = avq.make_agent(name, gym.make("avq/GridMaze-v0", slip=0.1), seed=5).learn(total_episodes=60)
    part = avq.make_agent(name, gym.make("avq/GridMaze-v0", slip=0.1), seed=5).learn(total_episodes=25)
    part.save(tmp_path / "m.zip")
    loaded = avq.load(tmp_path / "m.zip").learn(total_episodes=35)
    assert np.array_equal(whole.q_, loaded.q_) and whole.backups_ == loaded.backups_
    assert whole.episode_history()["steps"].tolist() == loaded.episode_history()["steps"].tolist()


def test_bad_planning_options_get_clear_errors():
    env = gym.make("avq/GridMaze-v0")
    with pytest.raises(ValueError, match="n_backups must be an integer >= 0, not -1"):
        avq.make_agent("tabular-ps", env, n_backups=-1)
    with pytest.raises(ValueError, match=r"v_min \(20.0\) must not exceed v_opt \(10.0\)"):
        avq.make_agent("avq-plan", env, v_min=20.0)
    with pytest.raises(ValueError, match="known_after must be an integer >= 1"):
        avq.make_agent("avq-plan", env, known_after=0)
    with pytest.raises(
        ValueError,
        match="'n_backups' is an option of planning.*'avq-maze' has no model; "
        "the agents that plan are 'avq', 'avq-plan', 'grid-ps', 'tabular-ps'$",
    ):
        avq.make_agent("avq-maze", env, n_backups=10)
    with pytest.raises(ValueError, match=r"split_threshold must be in \(0.0, inf\), not 0"):
        avq.make_agent("avq-plan", env, split_threshold=0)


# -- avq-plan's rules ---------------------------------------------------------------------------------

#: avq-plan's maze settings (the class's own defaults are those of tasks without collisions).
MAZE = {k: v for k, v in avq.agents.registry.DEFAULTS["avq-plan"]["avq/GridMaze-v0"].items() if k != "scale"}


def plan_agent(**kw):
    agent = avq.PlanningAVQ(gym.make("avq/GridMaze-v0", layout="open5"), scale=1.0, seed=0, **{**MAZE, **kw})
    agent._setup()
    agent._is_setup = True
    return agent


def remember(agent, xs, a, x, R, disc=1.0, crossing=False):
    """Store a transition from xs to x (cells by the current codebook) in the memory and the model (``crossing``:
    it ended only because the cell changed)."""
    ag = agent._ag
    size = int(ag.S[SIZE])

    def cell(p):
        return int(np.argmin(((ag.V[:size] - np.asarray(p, float)) ** 2).sum(axis=1)))

    i, j = cell(xs), cell(x)
    t = int(ag.S[MEM_POS])
    ag.xs[:] = xs  # (the current transition's start)
    memory.remember(ag, np.asarray(x, float), a, i, j, R, disc, crossing)
    agent._make_room()
    memory.record_with_start(
        agent._model.a, agent._ag.e_xs, ag.mem_x, t, i, a, R, disc, memory.successor(i, j, crossing), 1
    )
    return i, j


def add_cell(agent, x):
    agent._make_room()
    return core._new_cell(agent._ag, agent._model.a, np.asarray(x, float))


def test_appending_a_cell_moves_the_remembered_transitions_that_now_start_or_end_in_it():
    agent = plan_agent()
    add_cell(agent, (1.0, 1.0))
    add_cell(agent, (5.0, 1.0))
    remember(agent, (1, 1), 1, (4, 1), -3.0)  # 0 -> 1
    remember(agent, (1, 2), 1, (2, 2), -1.0)  # 0 -> 0
    m = agent._model.a
    assert m.cnt[0, 1] == 2 and m.cnt[1, 1] == 0
    agent._make_room()
    c = core.append_cell(agent._ag, agent._model.a, np.array([2.0, 2.0]))
    assert c == 2
    # The second transition's end (2, 2) is the new vector itself: it moves to cell 2. Its start (1, 2) lies at
    # distance 1 from both (1, 1) and (2, 2): a tie stays with the lower index, cell 0. The first is unchanged.
    assert agent._ag.mem_i[:2].tolist() == [[1, 0, 1, 0], [1, 0, 2, 0]]
    assert m.cnt[0, 1] == 2 and m.cnt[2, 1] == 0
    assert agent._ag.e_xs[: m.C[_model.N_EDGES]].sum(axis=0).tolist() == [2.0, 3.0]  # the starts moved with them


def test_the_value_slope_is_the_return_per_distance_travelled_unless_given():
    P, F = np.zeros(len(PlanParam)), np.zeros(N_F)
    P[PlanParam.VALUE_SLOPE] = -1.0
    assert core.value_slope(P, F) == 0.0
    F[SLOPE_SUM], F[SLOPE_N] = 3.0 + 5.0, 2
    assert core.value_slope(P, F) == 4.0
    P[PlanParam.VALUE_SLOPE] = 1.5
    assert core.value_slope(P, F) == 1.5


def test_disagreement_is_the_outcome_gap_beyond_what_distance_explains():
    agent = plan_agent()
    for x in ((1.0, 1.0), (5.0, 5.0), (5.0, 1.0)):
        add_cell(agent, x)
    m = agent._model.a
    # Settle cells 1 and 2 (every action known): V(1) = 6, V(2) = -20.
    for s, r in ((1, 6.0), (2, -20.0)):
        for a in range(4):
            m.cnt[s, a] = 1
            m.Q[s, a] = r
        m.V[s] = r
    # Cell 0, action 1, was seen going to cell 1 from (1, 1) with return -2 (outcome -2 + 6 = 4).
    remember(agent, (1, 1), 1, (5, 5), -2.0)
    out = np.zeros(3)
    # Now from (2, 1) it leads to cell 2: outcome -1 - 20 = -21. Gap 25, distance 1, slope 3: excess 22.
    agent._ag.xs[:] = 2.0, 1.0
    excess = core.disagreement(agent._ag, m, 0, 1, -21.0, 3.0, out)
    assert excess == pytest.approx(22.0) and out.tolist() == [1.0, 1.0, -21.0]


def test_split_cell_cuts_the_cell_around_the_two_starts_and_moves_its_transitions():
    agent = plan_agent()
    add_cell(agent, (3.0, 1.0))
    add_cell(agent, (3.0, 5.0))
    # Cell 0, action 1 (East): from (1, 1) and (2, 1) to cell 0 (one successor, mean start (1.5, 1)); from
    # (1, 3), which ties between (3, 1) and (3, 5) and so is in cell 0, to (3, 4) in cell 1.
    for xs, x in (((1, 1), (3, 1)), ((2, 1), (4, 1)), ((1, 3), (3, 4))):
        remember(agent, xs, 1, x, -1.0)
    assert agent._ag.mem_i[:3].tolist() == [[1, 0, 0, 0], [1, 0, 0, 0], [1, 0, 1, 0]]
    c = core.split_cell(agent._ag, agent._model.a, 0, 1, np.array([1.0, 1.0]), np.array([1.0, 3.0]), -1.0, agent.d_min)
    assert c == 2
    # Each successor's transitions go with the seed nearer their mean start: cell 0's (mean (1.5, 1)) with
    # (1, 1), cell 1's ((1, 3)) with (1, 3). The cell's vector moves to (1.5, 1); (1, 3) is the new cell.
    assert agent._ag.V[0].tolist() == [1.5, 1.0] and agent._ag.V[2].tolist() == [1.0, 3.0]
    # By the new vectors the third transition starts in cell 2 and still ends in cell 1 ((3, 4): 1 from
    # (3, 5), sqrt(5) from (1, 3)); the others stay in cell 0.
    assert agent._ag.mem_i[:3].tolist() == [[1, 0, 0, 0], [1, 0, 0, 0], [1, 2, 1, 0]]
    m = agent._model.a
    assert m.cnt[2, 1] == 1 and m.cnt[0, 1] == 2
    assert int(m.C[BACKUPS]) == 0 and m.hpos[0] >= 0 and m.hpos[2] >= 0  # both queued for a backup


def test_split_cell_refuses_mean_starts_within_d_min_of_each_other():
    # Two successors of (0, 0), from (1, 1) to cell 1 and from (2, 2) to cell 0: the groups' mean starts are
    # sqrt(2) apart, within d_min = 5.
    agent = plan_agent(d_min=5.0)
    add_cell(agent, (3.0, 3.0))
    add_cell(agent, (20.0, 20.0))
    remember(agent, (1, 1), 0, (20, 20), -10.0)
    remember(agent, (2, 2), 0, (2, 1), -1.0)
    before = agent._ag.V[:2].copy()
    seeds = (np.array([1.0, 1.0]), np.array([2.0, 2.0]))
    assert core.split_cell(agent._ag, agent._model.a, 0, 0, *seeds, -1.0, agent.d_min) == -1
    assert np.array_equal(agent._ag.V[:2], before) and agent.n_cells == 2
    # A floor below d_min (the outcome split's, once halved twice: finer_when_settled) lets it through.
    assert core.split_cell(agent._ag, agent._model.a, 0, 0, *seeds, -1.0, agent.d_min / 4) == 2
    assert agent._ag.V[2].tolist() == [2.0, 2.0]


def test_avq_plan_grows_few_cells_and_solves_the_paper_maze():
    def env():
        return gym.make("avq/GridMaze-v0")

    agent = avq.make_agent("avq-plan", env(), seed=0)
    for _ in range(20):
        agent.learn(total_episodes=10)
        if avq.evaluate_maze(agent, env())["success_rate"] >= 0.95:
            break
    assert avq.evaluate_maze(agent, env())["success_rate"] >= 0.95
    assert agent.n_cells < 98 and agent.num_timesteps < 20_000


def test_split_cell_refuses_a_mean_start_within_d_min_of_another_vector():
    # Cell 0 at (2, 2), cell 1 at (2, 5). Decision 0 from (1, 2) to cell 0, and from (3, 1) and (3, 3) to cell 1
    # (that successor's mean start: (3, 2)). Cut around (1, 2) and (3, 1): the groups' mean starts are (1, 2)
    # and (3, 2). With another vector at (4, 2), at distance 1 = d_min of (3, 2), the split is refused
    # (docs: explanation/paper.md, Growing); the starts (3, 1) and (3, 3) tie between (2, 2) and (4, 2): cell 0.
    for extra, expected in ((None, 2), ((4.0, 2.0), -1)):
        agent = plan_agent(d_min=1.0)
        add_cell(agent, (2.0, 2.0))
        add_cell(agent, (2.0, 5.0))
        if extra is not None:
            add_cell(agent, extra)
        for xs, x in (((1, 2), (1, 1)), ((3, 1), (2, 5)), ((3, 3), (2, 5))):
            assert remember(agent, xs, 0, x, -1.0)[0] == 0
        before = agent._ag.V[: agent.n_cells].copy()
        got = core.split_cell(
            agent._ag, agent._model.a, 0, 0, np.array([1.0, 2.0]), np.array([3.0, 1.0]), -1.0, agent.d_min
        )
        assert got == expected
        if expected < 0:
            assert np.array_equal(agent._ag.V[: agent.n_cells], before) and agent.n_cells == 3
        else:
            assert agent._ag.V[0].tolist() == [1.0, 2.0] and agent._ag.V[2].tolist() == [3.0, 2.0]


def test_cycle_split_gives_the_square_of_a_known_return_a_cell(scripted):
    # One action, cells at (0, 0) and (4, 0). The observations go 0 -> 1 -> 0 -> 1 -> 0 (cells) and end at the
    # goal. The third and fourth transitions return into the cell the decision before left; only the fourth
    # returns by two decisions the model knew (each pair tried once before): its square (1, 0) gets a cell.
    steps = [
        ((3, 0), -1.0, False, False, False),
        ((1, 0), -1.0, False, False, False),
        ((3, 0), -1.0, False, False, False),
        ((1, 0), -1.0, False, False, False),
        ((3, 0), 5.0, True, False, False),
    ]
    env = scripted([((0, 0), steps)], n_actions=1)
    agent = avq.PlanningAVQ(
        env,
        **{**MAZE, "scale": 1.0, "d_min": 0.1, "collision_growth": False, "outcome_split": False, "cycle_split": True},
        seed=0,
    )
    agent._setup()
    agent._is_setup = True
    add_cell(agent, (0.0, 0.0))
    add_cell(agent, (4.0, 0.0))
    agent.learn(total_episodes=1)
    assert agent.n_cells == 3 and agent.codebook_[2].tolist() == [1.0, 0.0]
    # The last transition starts in the new cell: (2, 0) -> 1, the episode's end.
    assert agent._ag.mem_i[4].tolist() == [0, 2, -1, 0]  # (the end of the episode: no crossing)


def test_the_models_public_queue_and_sweep_back_up_a_queued_state():
    """``agent.model_``: queue a state by hand and sweep it; its values come from the model."""
    agent = avq.make_agent("tabular-ps", gym.make("avq/GridMaze-v0"), seed=0).learn(total_episodes=20)
    model = agent.model_
    assert model.queued == 0 and model.n_states == agent.n_cells
    before = model.backups
    model.queue(0, 1.0)
    model.queue(1, 2.0)
    assert model.queued == 2
    assert model.sweep(1) == 1 and model.queued == 1  # the budget: one backup
    assert model.sweep(10) == 1 and model.queued == 0
    assert model.backups == before + 2


def test_the_maze_entry_lets_neighbouring_squares_of_a_wide_maze_be_cells_of_their_own():
    """The grid maze's ``d_min`` is a fraction of the maze's width (``scale`` None: the bounds' range), so it must
    stay under one square on wide mazes, or the planner cannot cut a corridor from the squares beside it and gets
    stuck (docs/results/merging.md, Resolution). 101 squares wide, one square is 0.01 of the width: 0.02 would keep
    two squares of a row from both being vectors; the entry's 0.001 does not. The robot keeps its own 0.02."""

    def row_neighbours(agent) -> int:
        v = agent.codebook_
        dx, dy = np.abs(v[:, None, 0] - v[None, :, 0]), np.abs(v[:, None, 1] - v[None, :, 1])
        return int(np.sum((dx == 1.0) & (dy == 0.0)) // 2)

    layout = ["G" + "." * 100, "." * 101]

    def maze():
        return gym.make("avq/GridMaze-v0", layout=layout, max_episode_steps=400)

    entry = avq.make_agent("avq-plan", maze(), seed=0).learn(total_episodes=20)
    coarse = avq.make_agent("avq-plan", maze(), seed=0, d_min=0.02).learn(total_episodes=20)
    assert entry.d_min < 1 / 100 and row_neighbours(entry) > 0
    assert row_neighbours(coarse) == 0
    assert avq.make_agent("avq-plan", "avq/RobotMaze-v0").d_min == 0.02
