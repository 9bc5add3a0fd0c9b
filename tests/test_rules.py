"""The rules beyond the paper (avq.rules), each a pure function checked on a situation written out by hand.

The paper's rules (collision_rule, may_append, similar_profiles, merge_profiles) are tested in
test_avq_rules.py beside the kernels that apply them."""

import numpy as np
import pytest

from avq import rules


@pytest.mark.parametrize(
    "same_cell, collision, done, expected",
    [
        (True, False, False, True),  # stays in its cell: the decision is repeated
        (False, False, False, False),  # entered another cell
        (True, True, False, False),  # hit a wall
        (True, False, True, False),  # the episode ended
    ],
)
def test_a_decision_goes_on_only_inside_its_cell(same_cell, collision, done, expected):
    assert rules.decision_goes_on(same_cell, collision, done) is expected


def test_repeat_limit():
    assert not rules.repeat_limit_reached(1_000, 0)  # 0: no limit
    assert not rules.repeat_limit_reached(4, 5)
    assert rules.repeat_limit_reached(5, 5)


def test_reward_jump_needs_a_change_of_at_least_the_trigger_and_a_previous_step():
    assert rules.reward_jump(-1.0, 0.0, steps_in_episode=2, r_trigger=1.0)  # |−1 − 0| = 1 >= 1
    assert not rules.reward_jump(-0.5, 0.0, steps_in_episode=2, r_trigger=1.0)  # 0.5 < 1
    assert not rules.reward_jump(-5.0, 0.0, steps_in_episode=1, r_trigger=1.0)  # the first step has no previous


def test_value_jump():
    assert rules.value_jump(-2.0, 2.0) and rules.value_jump(3.0, 2.0)
    assert not rules.value_jump(1.999, 2.0)
    assert not rules.value_jump(1e9, 0.0)  # 0: off


def test_collision_split_only_where_the_action_is_still_the_cells_best():
    # Q[i] = (5, 2): action 0 greedy and worth more than chi = -50; x is 0.4 from the cell's vector.
    q = np.array([5.0, 2.0])
    assert rules.collision_split(0.4, np.argmax(q) == 0, q[0], -50.0)
    assert not rules.collision_split(0.4, np.argmax(q) == 1, q[1], -50.0)  # not the greedy action
    assert not rules.collision_split(0.0, True, 5.0, -50.0)  # x is the cell's own vector
    assert not rules.collision_split(0.4, True, -50.0, -50.0)  # already condemned to chi


def test_a_cycle_is_a_return_to_the_cell_before():
    assert rules.closes_cycle(prev_cell=3, cell=7, next_cell=3)
    assert not rules.closes_cycle(prev_cell=3, cell=7, next_cell=4)
    assert not rules.closes_cycle(prev_cell=3, cell=3, next_cell=3)  # no move at all is not a cycle


def test_stayed_too_long():
    # split_after 5, d_min 0.5: a decision 5 steps old, x at distance 0.6 (squared 0.36) from every vector.
    assert rules.stayed_too_long(5, 5, 0.36, 0.5)
    assert not rules.stayed_too_long(4, 5, 0.36, 0.5)  # not yet 5 steps
    assert not rules.stayed_too_long(5, 5, 0.25, 0.5)  # within d_min (0.25 = 0.5²): no room for a vector
    assert not rules.stayed_too_long(99, 0, 9.0, 0.5)  # 0: off


def test_outcome_split_needs_a_disagreement_that_matters():
    # The outcome differs by 14 where distance explains 3: excess 11 over a threshold of 10.
    assert rules.outcome_disagrees(14.0 - 3.0, 10.0)
    assert not rules.outcome_disagrees(10.0, 10.0)
    # The worse outcome (-20) against the next best decision (-12): splitting changes the policy.
    assert rules.split_matters(-20.0, -12.0)
    assert not rules.split_matters(-20.0, -25.0)


def test_merge_guards():
    # Now episode 10; cells made in episodes 4 and 7; merge_age 3: both have lived at least 3.
    assert rules.old_enough(10, 4, 7, 3)
    assert not rules.old_enough(10, 4, 8, 3)
    assert rules.old_enough(10, 10, 10, 0)  # 0: no guard
    assert rules.same_greedy_action(np.array([1.0, 3.0, 2.0]), np.array([0.0, 0.5, 0.1]))
    assert not rules.same_greedy_action(np.array([1.0, 3.0, 2.0]), np.array([0.0, 0.5, 0.9]))


def test_stale_cell():
    # prune_after 4, now episode 20: made in episode 10, last decision in 16.
    assert rules.stale_cell(20, 10, 16, 4)
    assert not rules.stale_cell(20, 10, 17, 4)  # a decision 3 episodes ago
    assert not rules.stale_cell(20, 17, 10, 4)  # made 3 episodes ago
