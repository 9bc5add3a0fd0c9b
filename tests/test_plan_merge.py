"""avq-plan's merging (agents/plan/merge.py) and the model's decisions that go on (agents/plan/model.py, CONT):
each rule set up by hand with the numbers written out, then the agent that trains with them (both paths, resume)."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq import quantizer
from avq.agents.plan import explore, kernels, memory, merge, model as _model
from avq.agents.plan.model import CONT, Model
from avq.agents.plan.state import GEOM, MEM_N, MEM_POS, SIZE, PlanIntParam
from avq.rules import merged_decision_leaves

MAZE = {k: v for k, v in avq.agents.registry.DEFAULTS["avq-plan"]["avq/GridMaze-v0"].items() if k != "scale"}


# -- the model: a decision that goes on ------------------------------------------------------------------


def one_state_model(known=1):
    mdl = Model(2, 10.0, -100.0, known, 1e-9)
    mdl.add_state()
    mdl.reserve(edges=8)
    return mdl


def test_a_transition_that_goes_on_is_valued_by_the_pairs_own_value():
    mdl = one_state_model()
    m = mdl.a
    # (0, 0): once it went on inside the cell (return -1, discount 0.5), once it left to the end (return -1).
    _model.record(m, 0, 0, -1.0, 0.5, CONT, 1)
    _model.record(m, 0, 0, -1.0, 1.0, -1, 1)
    _model.record(m, 0, 1, -5.0, 1.0, -1, 1)
    assert m.cnt[0].tolist() == [2, 1] and m.cint[0].tolist() == [1, 0]
    _model.settle(m, 0, 100)
    # Q = -1 - 1 + 0.5 Q  over both:  2 Q = -2 + 0.5 Q  ->  Q = -2 / (2 - 0.5) = -4/3.
    assert m.Q[0, 0] == pytest.approx(-4.0 / 3.0) and m.Q[0, 1] == -5.0
    # Removing the transition that went on takes its count with it.
    _model.record(m, 0, 0, -1.0, 0.5, CONT, -1)
    _model.settle(m, 0, 100)
    assert m.cint[0, 0] == 0 and m.Q[0, 0] == -1.0


def test_a_pair_is_known_only_once_enough_of_its_transitions_left_the_cell():
    mdl = one_state_model(known=2)
    m = mdl.a
    for _ in range(3):
        _model.record(m, 0, 0, -1.0, 1.0, CONT, 1)
    _model.record(m, 0, 0, -1.0, 1.0, -1, 1)
    _model.settle(m, 0, 100)
    # Four transitions, one left: not known (2 needed), so it is worth v_opt.
    assert not _model.known(m, 0, 0) and m.Q[0, 0] == 10.0
    _model.record(m, 0, 0, -1.0, 1.0, -1, 1)
    _model.settle(m, 0, 100)
    # Five, two left: Q = -5 / (5 - 3) = -2.5.
    assert _model.known(m, 0, 0) and m.Q[0, 0] == -2.5


def test_successor_is_cont_only_for_a_crossing_that_ends_where_it_started():
    assert memory.successor(3, 3, 1) == CONT
    assert memory.successor(3, 3, 0) == 3  # (a collision or a stay: the agent decides again there)
    assert memory.successor(3, 4, 1) == 4
    assert memory.successor(3, -1, 0) == -1


def test_a_merge_is_refused_when_the_greedy_decision_would_not_leave():
    assert merged_decision_leaves(1, 1) and not merged_decision_leaves(0, 1) and not merged_decision_leaves(1, 2)


# -- the merge pass, on cells set by hand -------------------------------------------------------------------


def plan_agent(**kw):
    agent = avq.PlanningAVQ(
        gym.make("avq/GridMaze-v0", layout="open5"), scale=1.0, seed=0, **{**MAZE, "rho": 2.0, **kw}
    )
    agent._setup()
    agent._is_setup = True
    return agent


def add_cells(agent, *xs):
    for x in xs:
        agent._make_room()
        kernels._new_cell(agent._ag, agent._model.a, np.asarray(x, float))


def put(agent, xs, a, x, R, crossing=False, terminal=False):
    """A transition from xs to x in the memory and the model, its cells by the current codebook."""
    ag = agent._ag
    size = int(ag.S[SIZE])
    cell = lambda p: int(np.argmin(((ag.V[:size] - np.asarray(p, float)) ** 2).sum(axis=1)))  # noqa: E731
    i, j = cell(xs), (-1 if terminal else cell(x))
    t = int(ag.S[MEM_POS])
    ag.xs[:] = xs
    memory.remember(ag, np.asarray(x, float), a, i, j, R, 1.0, crossing)
    agent._make_room()
    memory.record_with_start(agent._model.a, ag.e_xs, ag.mem_x, t, i, a, R, 1.0, memory.successor(i, j, crossing), 1)


def converge(agent):
    for s in range(agent.n_cells):
        agent._model.queue(s, _model.FIRST)
    agent._model.sweep(100_000)


A, B, C = (1.0, 1.0), (3.0, 1.0), (1.0, 4.0)


def three_cells(agent, back_from_b=None):
    """Cells A, B, C; every decision ends the episode at -10 except East (1): from A it crosses into B at -2;
    from B it ends at -4 (or, with ``back_from_b``, crosses back into A at that return); from C it ends at -30."""
    add_cells(agent, A, B, C)
    for x in (A, B, C):
        for a in (0, 2, 3):
            put(agent, x, a, x, -10.0, terminal=True)
    put(agent, A, 1, B, -2.0 if back_from_b is None else back_from_b, crossing=True)
    if back_from_b is None:
        put(agent, B, 1, B, -4.0, terminal=True)
    else:
        put(agent, B, 1, A, back_from_b, crossing=True)
    put(agent, C, 1, C, -30.0, terminal=True)
    converge(agent)


def test_nearest_cells_are_listed_nearest_first_lowest_index_on_ties():
    V = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 1.0], [-2.0, 0.0], [5.0, 5.0]])
    out = np.zeros(3, dtype=np.int64)
    assert merge.nearest_cells(V, 5, 0, 3, np.ones(2), out) == 3 and out.tolist() == [2, 1, 3]
    assert merge.nearest_cells(V, 2, 0, 3, np.ones(2), out) == 1 and out[0] == 1


def test_two_cells_with_close_profiles_merge_and_the_model_composes_their_decisions():
    agent = plan_agent()
    three_cells(agent)
    m = agent._model.a
    # East from A: -2 then B's -4; every other decision -10. Profiles A [-10, -6, -10, -10], B [-10, -4, -10,
    # -10]: mean square 1, under rho 2. C's East is -30: 144 from A's, 169 from B's.
    assert m.Q[0].tolist() == [-10.0, -6.0, -10.0, -10.0] and m.Q[1].tolist() == [-10.0, -4.0, -10.0, -10.0]
    assert merge.exits_after_merge(m, 0, 1, 1) == 1  # (B's East leaves; A's went into B)
    geom = int(agent._ag.S[GEOM])
    assert merge.merge_pass(agent._ag, m) == 1
    assert agent.n_cells == 2 and int(agent._ag.S[GEOM]) == geom + 1
    # A's vector moves to the midpoint, B is gone and C moves down to index 1, with its values.
    assert agent.codebook_.tolist() == [[2.0, 1.0], [1.0, 4.0]]
    assert m.Q[1].tolist() == [-10.0, -30.0, -10.0, -10.0]
    # The memory's cells follow; the crossing from A into B now ends in its own cell: it goes on.
    rows = agent._ag.mem_i[: int(agent._ag.S[MEM_N])].tolist()
    assert rows[9] == [1, 0, 0, 1] and rows[10] == [1, 0, -1, 0] and rows[11] == [1, 1, -1, 0]
    assert m.cnt[0].tolist() == [2, 2, 2, 2] and m.cint[0].tolist() == [0, 1, 0, 0]
    converge(agent)
    # East in the merged cell: -2, goes on, -4: Q = (-2 - 4) / (2 - 1) = -6.
    assert m.Q[0].tolist() == [-10.0, -6.0, -10.0, -10.0]
    # The model is exactly what recording the memory in the new cells gives: its starts' sums included.
    edges = int(m.C[_model.N_EDGES])
    assert edges == 9 and agent._ag.e_xs[:edges].sum(axis=0).tolist() == list(
        agent._ag.mem_x[: int(agent._ag.S[MEM_N]), :2].sum(axis=0)
    )


def test_a_merge_whose_greedy_decision_would_never_leave_is_refused():
    agent = plan_agent()
    # East from A crosses into B and East from B back into A, at no cost: both cells' greedy decision, and after
    # a merge it would never leave the cell (the paper's chi). The profiles are equal (mean square 0).
    three_cells(agent, back_from_b=0.0)
    m = agent._model.a
    assert np.argmax(m.Q[0]) == 1 and np.argmax(m.Q[1]) == 1 and np.array_equal(m.Q[0], m.Q[1])
    assert merge.exits_after_merge(m, 0, 1, 1) == 0
    assert merge.merge_pass(agent._ag, m) == 0 and agent.n_cells == 3


def test_a_merge_that_the_outcome_split_would_undo_is_refused():
    # East in the merged cell: from A (1, 1) it went on (outcome -2 + Q = -2 - 6 = -8), from B (3, 1) it ended at
    # -4: a gap of 4 between starts 2 apart. With split_threshold 3 and no slope the split would cut the merged
    # cell again: refused. With slope 1 the distance explains 2 of the 4: under 3, merged.
    for threshold, slope, merges in ((10.0, None, 1), (3.0, None, 0), (3.0, 1.0, 1)):
        agent = plan_agent(split_threshold=threshold, value_slope=slope)
        three_cells(agent)
        m = agent._model.a
        assert merge.outcomes_agree(agent._ag, m, 0, 1, 1) == bool(merges)
        assert merge.merge_pass(agent._ag, m) == merges


def test_with_merge_same_action_cells_whose_greedy_actions_differ_do_not_merge():
    for same_action, merges in ((True, 0), (False, 1)):
        agent = plan_agent(rho=20.0, merge_same_action=same_action)
        add_cells(agent, A, B)
        # A: East crosses into B at -1, the rest -10; B: North ends at -3 (its greedy), East at -4, the rest -10.
        # Profiles A [-10, -4, -10, -10] (East: -1 + V(B) = -4), B [-3, -4, -10, -10]: mean square 49 / 4.
        for x, returns in ((A, (-10.0, None, -10.0, -10.0)), (B, (-3.0, -4.0, -10.0, -10.0))):
            for a, r in enumerate(returns):
                if r is not None:
                    put(agent, x, a, x, r, terminal=True)
        put(agent, A, 1, B, -1.0, crossing=True)
        converge(agent)
        m = agent._model.a
        assert m.Q[0].tolist() == [-10.0, -4.0, -10.0, -10.0] and m.Q[1].tolist() == [-3.0, -4.0, -10.0, -10.0]
        assert merge.merge_pass(agent._ag, m) == merges


def test_no_merge_above_rho_beyond_the_nearest_cells_or_once_the_memory_is_full():
    agent = plan_agent(rho=0.5)  # (A and B differ by 1)
    three_cells(agent)
    assert merge.merge_pass(agent._ag, agent._model.a) == 0
    agent = plan_agent(merge_neighbours=1)
    add_cells(agent, (8.0, 8.0))  # (a cell never visited: A's nearest is B and B's is A, so they still merge)
    three_cells(agent)
    assert merge.merge_pass(agent._ag, agent._model.a) == 1
    agent = plan_agent(memory=12)  # (three_cells remembers 12 transitions: the memory is full)
    three_cells(agent)
    assert int(agent._ag.S[MEM_N]) == agent._ag.IP[PlanIntParam.MEMORY]
    assert merge.merge_pass(agent._ag, agent._model.a) == 0


def test_cells_with_an_untried_decision_do_not_merge():
    agent = plan_agent()
    add_cells(agent, A, B)
    for x in (A, B):
        for a in (0, 1, 2):
            put(agent, x, a, x, -10.0, terminal=True)
    converge(agent)  # (West, 3, untried in both: worth v_opt in both, so the profiles agree)
    assert np.array_equal(agent._model.a.Q[0], agent._model.a.Q[1])
    assert merge.merge_pass(agent._ag, agent._model.a) == 0


def test_the_merge_pass_finds_the_cells_neighbours_again_only_when_the_codebook_changed():
    agent = plan_agent(rho=0.5, merge_neighbours=2)  # (A and B differ by 1: no merge)
    three_cells(agent)
    ag, m = agent._ag, agent._model.a
    assert ag.near[0, 0] == -1
    assert merge.merge_pass(ag, m) == 0
    # A (1, 1): B at 2, C at 3; B (3, 1): A at 2, C at sqrt(13); C (1, 4): A at 3, B at sqrt(13).
    assert ag.near[0, 0] == ag.S[GEOM] and ag.near[1:4].tolist() == [[1, 2], [0, 2], [0, 1]]
    # A vector moved without the codebook's count of changes: the table is kept as it was found.
    ag.V[2] = (3.0, 2.0)
    assert merge.merge_pass(ag, m) == 0 and ag.near[1:4].tolist() == [[1, 2], [0, 2], [0, 1]]
    # Counted as a change: found again (C now at 1 from B, sqrt(5) from A).
    ag.S[GEOM] += 1
    assert merge.merge_pass(ag, m) == 0
    assert ag.near[0, 0] == ag.S[GEOM] and ag.near[1:4].tolist() == [[1, 2], [2, 0], [1, 0]]


def test_the_merge_pass_neighbour_table_is_that_of_the_codebook_throughout_training(tmp_path):
    agent = avq.make_agent("avq", gym.make("avq/GridMaze-v0"), seed=2)
    checked = 0
    for _ in range(40):
        agent.learn(total_episodes=5)
        ag, size = agent._ag, agent.n_cells
        if ag.near[0, 0] == ag.S[GEOM]:
            checked += 1
            k = ag.near.shape[1]
            for i in range(size):
                out = np.zeros(k, dtype=np.int64)
                found = merge.nearest_cells(ag.V, size, i, k, ag.inv_scale, out)
                assert ag.near[1 + i, :found].tolist() == out[:found].tolist()
    assert checked > 10 and agent.episode_history()["merges"].sum() > 0
    agent.save(tmp_path / "a.zip")
    assert avq.load(tmp_path / "a.zip")._ag.near[0, 0] == -1  # (found again for the loaded codebook)


def test_after_a_merge_a_remembered_observation_is_placed_among_its_cell_and_the_merged_cells():
    # Vectors 0 (0, 0), 1 (2, 0), 2 (10, 0), 3 (5, 4), 4 (20, 0); the pairs (0, 1) and (2, 4) merge: midpoints (1, 0)
    # in slot 0 and (15, 0) in slot 1, and (5, 4) moves down to slot 2.
    V = np.array([[0.0, 0.0], [2.0, 0.0], [10.0, 0.0], [5.0, 4.0], [20.0, 0.0]])
    pairs = np.array([[0, 1], [2, 4]])
    mapping = quantizer.merge_kernel(V, 5, pairs)
    assert mapping.tolist() == [0, 0, 1, 2, 1] and V[:3].tolist() == [[1.0, 0.0], [15.0, 0.0], [5.0, 4.0]]
    half, merged = np.array([True, True, True, False, True]), np.array([0, 1])
    X = np.array([[2.0, 0.0], [5.0, 1.0], [5.0, 4.5], [12.0, 1.0]])

    def cell(t, before):
        return memory.cell_after_merge(V, 3, X, t, 0, before, mapping, half, merged, np.ones(2))

    assert cell(0, 1) == 0  # (2, 0) was in a half (1): among all, nearest (1, 0) (squared 1)
    assert cell(1, 3) == 2  # (5, 1) was in 3: 9 from (5, 4), 17 from (1, 0), 101 from (15, 0): its own cell
    V[2] = (9.0, 9.0)  # (cell 3, now 2, far: the merged cells take what lies nearer them)
    assert cell(3, 3) == 1  # (12, 1): 73 from (9, 9), 10 from (15, 0)
    assert cell(2, 3) == 0  # (5, 4.5): 36.25 from both (1, 0) and (9, 9): the lower index


def test_with_merging_every_remembered_transition_lies_in_the_cells_of_its_observations():
    """What the merge pass's rebuild relies on (memory.cell_after_merge): the memory's start and end cells are those
    of the codebook, also for a transition whose start a cell appended in its last step took over."""
    agent = avq.make_agent("avq-plan", gym.make("avq/GridMaze-v0"), seed=0, rho=25.0, cycle_split=True)
    for _ in range(60):
        agent.learn(total_episodes=1)
        ag = agent._ag
        size, n = int(ag.S[SIZE]), ag.xs.shape[0]
        mem_x, mem_i = ag.mem_x[: int(ag.S[MEM_N])], ag.mem_i[: int(ag.S[MEM_N])]
        starts = agent.cells(mem_x[:, :n])
        ends = np.where(mem_i[:, 2] >= 0, agent.cells(mem_x[:, n:]), -1)
        assert np.array_equal(mem_i[:, 1], starts) and np.array_equal(mem_i[:, 2], ends), agent.num_episodes
        assert agent.codebook_.shape[0] == size
    assert agent.episode_history()["merges"].sum() > 0 and agent.episode_history()["appends"].sum() > 0


# -- the agent ----------------------------------------------------------------------------------------------


def trained(fused, seed=1, episodes=150, **kw):
    agent = avq.make_agent("avq-plan", gym.make("avq/GridMaze-v0"), seed=seed, fused=fused, rho=20.0, **kw)
    return agent.learn(total_episodes=episodes)


def test_merging_agent_is_the_same_on_both_paths_and_merges():
    a, b = trained(True), trained(False)
    assert np.array_equal(a.codebook_, b.codebook_) and np.array_equal(a.q_, b.q_)
    ha, hb = a.episode_history(), b.episode_history()
    for key in ("steps", "return", "n_cells", "appends", "merges", "refused", "decisions"):
        assert np.array_equal(ha[key], hb[key]), key
    assert ha["merges"].sum() > 0
    plain = avq.make_agent("avq-plan", gym.make("avq/GridMaze-v0"), seed=1).learn(total_episodes=150)
    assert a.n_cells < plain.n_cells


def test_merging_agent_resumes_exactly(tmp_path):
    straight = trained(True, episodes=120)
    first = trained(True, episodes=60)
    first.save(tmp_path / "half.zip")
    resumed = avq.load(tmp_path / "half.zip", env=gym.make("avq/GridMaze-v0")).learn(total_episodes=60)
    assert np.array_equal(straight.codebook_, resumed.codebook_) and np.array_equal(straight.q_, resumed.q_)
    assert np.array_equal(straight.episode_history()["merges"], resumed.episode_history()["merges"])


def test_bad_merge_options_get_clear_errors():
    env = gym.make("avq/GridMaze-v0")
    with pytest.raises(ValueError, match="rho"):
        avq.make_agent("avq-plan", env, rho=-1.0)
    with pytest.raises(ValueError, match="merge_neighbours"):
        avq.make_agent("avq-plan", env, merge_neighbours=0)
    with pytest.raises(ValueError, match="known_radius"):
        avq.make_agent("avq-plan", env, known_radius=-0.1)
    with pytest.raises(
        ValueError,
        match="'merge_neighbours' is an option of merging cells under a learned model, and agent 'avq-paper' has no "
        "model; the agents that merge under a model are ",
    ):
        avq.make_agent("avq-paper", env, merge_neighbours=3)
    with pytest.raises(ValueError, match="unknown parameter 'rho' for agent 'tabular-ps'"):
        avq.make_agent("tabular-ps", env, rho=20.0)


# -- decisions never tried from near here (known_radius) ----------------------------------------------------


def test_a_decision_never_tried_near_the_observation_is_worth_v_opt_while_learning():
    for radius, expected in ((0.5, 1), (None, 0)):
        agent = plan_agent(known_radius=radius)
        add_cells(agent, A, B)
        # Cell A: North ends at -5 (the greedy), South and West at -10, all from (1, 1); East at -20, tried only
        # from (1, 2).
        for a, r in ((0, -5.0), (2, -10.0), (3, -10.0)):
            put(agent, A, a, A, r, terminal=True)
        put(agent, (1.0, 2.0), 1, A, -20.0, terminal=True)
        converge(agent)
        ag, m = agent._ag, agent._model.a
        x = np.array([1.0, 1.4])  # (0.4 from (1, 1), 0.6 from (1, 2))
        assert explore.tried_near(ag, m, 0, 0, x, 0.5) and not explore.tried_near(ag, m, 0, 1, x, 0.5)
        agent._draws.reserve()
        # Within 0.5: East was never tried from near (1, 1.4), so it is worth v_opt (10) for this decision.
        assert explore.decide(ag, m, agent._draws.src, 0, x) == expected
        assert m.Q[0].tolist() == [-5.0, -20.0, -10.0, -10.0]  # (the planned values do not change)
