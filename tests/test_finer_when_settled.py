"""The floor of the growth from decisions, halving as the cells settle (``finer_when_settled``,
avq.agents.plan.resolution): the rule on a model set by hand, the floor where a decision grows a cell, the codebook
it leaves, and a run saved and resumed across the halving."""

import math

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq.agents._value_weights import MIN_CELLS
from avq.agents.plan import kernels, model as _model
from avq.agents.plan.resolution import FINER_SHARE, decision_floor, refine_when_settled
from avq.agents.plan.state import CELL, DEC_STEPS, FINER, SIZE


def learned(finer: int = 0, episodes: int = 3, **params):
    return avq.PlanningAVQ(gym.make("MountainCar-v0"), seed=0, finer_when_settled=finer, **params).learn(
        total_episodes=episodes
    )


def settle(agent, cells: int) -> None:
    """The first ``cells`` cells settled (every decision tried ``known`` times), the rest with nothing known."""
    m = agent._model.a
    m.cnt[: agent.n_cells] = 0
    m.cint[: agent.n_cells] = 0
    m.cnt[:cells] = m.C[_model.KNOWN]


def test_the_floor_halves_once_nine_cells_in_ten_are_settled_and_no_more_often_than_the_limit():
    agent = learned()
    ag, m, n = agent._ag, agent._model.a, agent.n_cells
    assert n >= MIN_CELLS and FINER_SHARE == 0.9 and ag.S[FINER] == 0
    need = math.ceil(FINER_SHARE * n)
    settle(agent, need - 1)
    assert not refine_when_settled(ag, m, 2) and ag.S[FINER] == 0
    assert decision_floor(ag.P, ag.S) == agent.d_min
    settle(agent, need)
    assert refine_when_settled(ag, m, 2) and ag.S[FINER] == 1
    assert decision_floor(ag.P, ag.S) == agent.d_min / 2
    assert refine_when_settled(ag, m, 2) and ag.S[FINER] == 2
    assert decision_floor(ag.P, ag.S) == agent.d_min / 4
    assert not refine_when_settled(ag, m, 2) and ag.S[FINER] == 2  # (the limit)
    assert not refine_when_settled(ag, m, 0)


def test_with_fewer_cells_than_the_fit_needs_the_floor_stays():
    agent = learned(episodes=1, max_cells=MIN_CELLS - 1)
    ag = agent._ag
    for _ in range(5):
        agent.learn(total_episodes=1)
    assert ag.S[SIZE] == MIN_CELLS - 1
    settle(agent, agent.n_cells)
    assert not refine_when_settled(ag, agent._model.a, 2) and ag.S[FINER] == 0


@pytest.mark.parametrize("finer, grows", [(0, False), (1, True)])
def test_a_decision_that_stays_in_its_cell_grows_one_only_beyond_the_floor(finer, grows):
    # A decision has stayed split_after - 1 steps in cell 0; the next step stays there, 0.75 d_min from its vector:
    # within d_min (it goes on), beyond the floor once halved (it ends there, and end_transition grows a cell).
    agent = learned()
    ag = agent._ag
    ag.S[CELL], ag.S[DEC_STEPS], ag.S[FINER] = 0, agent.split_after - 1, finer
    d2 = (0.75 * agent.d_min) ** 2
    assert kernels.goes_on(ag, -1.0, 0, d2, False, False) is not grows


def test_the_cells_come_nearer_than_d_min_down_to_a_quarter_of_it():
    def nearest(agent):
        z = agent.codebook_ / agent.scale_
        d = np.sqrt(((z[:, None] - z[None]) ** 2).sum(-1))
        return d[np.triu_indices(len(z), 1)].min()

    coarse, fine = learned(0, episodes=200), learned(2, episodes=200)
    assert coarse._ag.S[FINER] == 0 and fine._ag.S[FINER] == 2
    assert nearest(coarse) > coarse.d_min
    assert fine.d_min / 4 < nearest(fine) < fine.d_min
    assert fine.n_cells > 2 * coarse.n_cells


@pytest.mark.parametrize("first", [5, 60])  # saved before the floor halves, and after
def test_a_run_resumes_exactly_across_the_halving(tmp_path, first):
    whole = learned(2, episodes=80)
    part = learned(2, episodes=first)
    loaded = avq.load(part.save(tmp_path / "m.zip")).learn(total_episodes=80 - first)
    assert whole._ag.S[FINER] == 2 and (part._ag.S[FINER] > 0) == (first == 60)
    assert np.array_equal(loaded.codebook_, whole.codebook_) and np.array_equal(loaded.q_, whole.q_)
    assert loaded.episode_history()["return"].tolist() == whole.episode_history()["return"].tolist()


def test_a_bad_setting_gets_a_clear_error_and_the_maze_entries_keep_it_off():
    with pytest.raises(ValueError, match="finer_when_settled.*an integer >= 0"):
        avq.PlanningAVQ(gym.make("MountainCar-v0"), finer_when_settled=-1)
    for task in ("avq/GridMaze-v0", "avq/RobotMaze-v0"):
        assert avq.make_agent("avq", task, seed=0).get_params()["finer_when_settled"] == 0
    assert avq.make_agent("avq", "MountainCar-v0", seed=0).get_params()["finer_when_settled"] == 1
