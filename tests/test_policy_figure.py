"""The picture of what was learned on a Box task (``avq plot``, :func:`avq.plotting.plot_policy`) and the learning
curves' seeds that never learned: each checked against a situation set up by hand and worked out by hand."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import avq
from avq.cli import main
from avq.plotting import learning_curves_figure, never_learned, plot_policy, policy_map
from avq.quantizer import Codebook


class Box3Env(gym.Env):
    """A task that only lends its spaces: observations in ``[0, 4]^n``, ``k`` discrete actions."""

    def __init__(self, n=2, k=3):
        self.observation_space = spaces.Box(0.0, 4.0, shape=(n,), dtype=np.float64)
        self.action_space = spaces.Discrete(k)


class HandCells:
    """An agent with hand-placed cells: the nearest centre in its metric (avq's quantizer), one greedy action
    per cell. It answers what ``policy_map`` asks of an agent: ``cells``, ``predict``, ``codebook_``, ``scale_``."""

    size_unit = "cells"

    def __init__(self, centres, actions, scale=1.0):
        self.codebook_ = np.asarray(centres, dtype=float)
        self.greedy = np.asarray(actions)
        self.scale_ = np.broadcast_to(np.asarray(scale, dtype=float), (self.codebook_.shape[1],)).copy()
        self.env = Box3Env(n=self.codebook_.shape[1], k=int(self.greedy.max()) + 1)
        self.n_cells = len(self.codebook_)

    def get_params(self):
        return {}

    def cells(self, observations):
        return Codebook.from_vectors(self.codebook_, self.scale_).nearest_batch(observations)

    def predict(self, observations, deterministic=True):
        return self.greedy[self.cells(observations)], None


# Pixels of [0, 4]^2 at resolution 4: centres 0.5, 1.5, 2.5, 3.5 on each axis; rows are y upwards.
THREE = [(1.0, 1.0), (3.0, 1.0), (2.0, 3.0)]
# The nearest of THREE to each pixel (squared distances by hand; a tie, such as (0.5, 2.5) at 2.5 from
# cells 0 and 2, goes to the lower index):
THREE_CELLS = [
    [0, 0, 1, 1],  # y 0.5
    [0, 0, 1, 1],  # y 1.5
    [0, 2, 2, 1],  # y 2.5: (0.5, 2.5) ties 0 and 2 -> 0; (3.5, 2.5) ties 1 and 2 -> 1
    [2, 2, 2, 2],  # y 3.5
]


def test_three_hand_placed_cells_give_exactly_their_voronoi_regions_and_actions():
    agent = HandCells(THREE, actions=[1, 0, 1])
    view = policy_map(agent, dims=(0, 1), resolution=4)
    assert view.xs.tolist() == [0.5, 1.5, 2.5, 3.5] and view.ys.tolist() == [0.5, 1.5, 2.5, 3.5]
    assert view.cells.tolist() == THREE_CELLS
    assert view.actions.tolist() == np.array([1, 0, 1])[np.array(THREE_CELLS)].tolist()
    assert view.centres.tolist() == [list(c) for c in THREE] and view.at == {} and not view.projected
    assert view.names == ("x0", "x1") and view.action_names == ("action 0", "action 1")
    # Drawn the other way round: the same regions, transposed.
    assert policy_map(agent, dims=(1, 0), resolution=4).cells.tolist() == np.array(THREE_CELLS).T.tolist()


def test_a_slice_at_another_value_moves_the_border_as_worked_out_by_hand():
    # A = (0, 0, 0), B = (4, 0, 2): in the plane z = c the border is where x^2 + c^2 = (x - 4)^2 + (c - 2)^2,
    # x = 2.5 - c / 2 (a pixel on it goes to A, the lower index).
    agent = HandCells([(0.0, 0.0, 0.0), (4.0, 0.0, 2.0)], actions=[0, 1])
    for z, row in ((0.0, [0, 0, 0, 1]), (1.0, [0, 0, 1, 1]), (3.0, [0, 1, 1, 1])):  # borders 2.5, 2.0, 1.0
        view = policy_map(agent, dims=(0, 1), at={2: z}, resolution=4)
        assert view.at == {2: z}
        assert view.cells.tolist() == [row] * 4 and view.actions.tolist() == [row] * 4
    # The default slice is the middle of the range, z = 2: the border at x = 1.5, on the pixel, which goes to A.
    assert policy_map(agent, dims=(0, 1), resolution=4).cells.tolist() == [[0, 0, 1, 1]] * 4
    # The agent's own metric: x counting half (scale 2), ((x/2)^2 + z^2 = ((x-4)/2)^2 + (z-2)^2) puts the
    # border at x = 4 - 2z; at z = 0.5, x = 3 (against 2.25 unscaled).
    assert policy_map(agent, dims=(0, 1), at={2: 0.5}, resolution=4).cells.tolist() == [[0, 0, 1, 1]] * 4
    scaled = HandCells([(0.0, 0.0, 0.0), (4.0, 0.0, 2.0)], actions=[0, 1], scale=[2.0, 1.0, 1.0])
    assert policy_map(scaled, dims=(0, 1), at={2: 0.5}, resolution=4).cells.tolist() == [[0, 0, 0, 1]] * 4


def test_a_projection_takes_the_nearest_projected_centre_in_the_agents_scale():
    # Projected onto (x0, x1), the third dimension dropped: A (0, 0) and C (2, 4). At scale (1, 2) the border is
    # x^2 + (y/2)^2 = (x - 2)^2 + ((y - 4)/2)^2, i.e. 4x + 2y = 8; unscaled 4x + 8y = 20 (no pixel lies on either).
    agent = HandCells([(0.0, 0.0, 1.0), (2.0, 4.0, 3.0)], actions=[0, 1], scale=[1.0, 2.0, 1.0])
    view = policy_map(agent, dims=(0, 1), project=True, resolution=4)
    c = np.array([[0 if 4 * x + 2 * y <= 8 else 1 for x in view.xs] for y in view.ys])
    assert view.projected and view.at == {} and view.cells.tolist() == c.tolist()
    assert view.centres.tolist() == [[0.0, 0.0], [2.0, 4.0]]
    unscaled = HandCells([(0.0, 0.0, 1.0), (2.0, 4.0, 3.0)], actions=[0, 1])
    c = np.array([[0 if 4 * x + 8 * y <= 20 else 1 for x in view.xs] for y in view.ys])
    assert policy_map(unscaled, dims=(0, 1), project=True, resolution=4).cells.tolist() == c.tolist()


@pytest.fixture(scope="module")
def mountain_car_model(tmp_path_factory):
    """``avq`` on MountainCar-v0 for 3 episodes, saved."""
    agent = avq.make_agent("avq", gym.make("MountainCar-v0"), seed=0).learn(total_episodes=3)
    path = tmp_path_factory.mktemp("mc") / "model.zip"
    agent.save(path)
    return agent, path


def test_a_trained_agents_slice_is_its_own_cells_and_greedy_actions(mountain_car_model, tmp_path):
    agent, _ = mountain_car_model
    view = policy_map(agent, dims=(0, 1), resolution=30)
    gx, gy = np.meshgrid(view.xs, view.ys)
    obs = np.stack([gx.ravel(), gy.ravel()], axis=1)
    assert view.cells.ravel().tolist() == agent.cells(obs).tolist()
    assert view.actions.ravel().tolist() == agent.predict(obs)[0].tolist()
    assert view.xs[0] == pytest.approx(-1.2 + 1.8 / 60) and view.ys[-1] == pytest.approx(0.07 - 0.14 / 60)
    assert view.names == ("position", "velocity")
    assert view.action_names == ("accelerate left", "don't accelerate", "accelerate right")
    # In two dimensions a projection is the same picture as the slice.
    assert policy_map(agent, dims=(0, 1), project=True, resolution=30).cells.tolist() == view.cells.tolist()
    for suffix in (".pdf", ".svg", ".png"):
        out = plot_policy(agent, tmp_path / f"p{suffix}", resolution=30)
        assert out.stat().st_size > 1000
    assert (tmp_path / "p.svg").read_text()[:200].lstrip().startswith("<?xml")


def test_avq_plot_writes_the_figure_of_a_model_file_and_of_a_run_directory(mountain_car_model, tmp_path, capsys):
    _, path = mountain_car_model
    out = tmp_path / "mc.pdf"
    assert main(["plot", str(path), "--dims", "1,0", "--out", str(out), "--resolution", "20"]) == 0
    assert out.read_bytes().startswith(b"%PDF") and f"wrote {out}" in capsys.readouterr().out
    run = tmp_path / "run"
    assert main(["train", "--env", "MountainCar-v0", "--episodes", "2", "--out", str(run), "--no-progress"]) == 0
    assert main(["plot", str(run), "--resolution", "20"]) == 0
    assert (run / "policy_0-1.png").stat().st_size > 1000
    assert main(["plot", str(run), "--project", "--resolution", "20"]) == 0
    assert (run / "policy_0-1_projected.png").is_file()


@pytest.mark.parametrize(
    "args,message",
    [
        (["--dims", "0,2"], "dims: this task has no dimension 2; its dimensions are 0 (position), 1 (velocity)"),
        (["--at", "3=0"], "at: this task has no dimension 3; its dimensions are 0 (position), 1 (velocity)"),
        (["--dims", "1,1"], "dims are both 1; give two different dimensions, e.g. 1,0"),
        (["--dims", "0"], "dims '0': give exactly two dimension numbers separated by a comma, e.g. 0,1"),
        (["--dims", "a,b"], "dims 'a,b': give two dimension numbers separated by a comma, e.g. 0,1"),
        (["--at", "0=0.1"], "at fixes dimension 0, which is drawn (dims 0,1); fix only the other dimensions"),
        (["--at", "5=x"], "at '5=x': 'x' is not a number; give e.g. 5=0.0"),
        (["--project", "--at", "1=0"], "a projection fixes no dimension"),
        (["--bounds", "1=3"], "bounds '1=3': give DIM=LOW:HIGH, e.g. 1=-3:3"),
    ],
)
def test_avq_plot_bad_input_names_the_value_and_the_fix(mountain_car_model, tmp_path, capsys, args, message):
    _, path = mountain_car_model
    assert main(["plot", str(path), *args, "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and not (tmp_path / "x.png").exists()


def test_avq_plot_of_a_missing_file_or_a_task_without_a_box_space_says_what_to_give(tmp_path, capsys):
    assert main(["plot", str(tmp_path / "nonexist.zip")]) == 2
    err = capsys.readouterr().err
    assert f"no such model file or run directory: {tmp_path / 'nonexist.zip'}; give a directory" in err
    tabular = avq.make_agent("tabular", gym.make("CliffWalking-v1"), seed=0).learn(total_episodes=1)
    tabular.save(tmp_path / "cliff.zip")
    assert main(["plot", str(tmp_path / "cliff.zip")]) == 2
    err = capsys.readouterr().err
    assert "a policy picture needs a flat Box observation space" in err and "Discrete(48)" in err
    assert "Traceback" not in err


def test_an_unbounded_dimension_without_centres_asks_for_bounds():
    agent = HandCells([(0.0, 0.0)], actions=[0])
    agent.env.observation_space = spaces.Box(np.array([0.0, -np.inf]), np.array([4.0, np.inf]), dtype=np.float64)
    with pytest.raises(ValueError, match=r"dimension 1 \(x1\) has no finite range.*bounds=\{1: \(-3, 3\)\}"):
        policy_map(agent)
    assert policy_map(agent, bounds="1=-3:5", resolution=4).ys.tolist() == [-2.0, 0.0, 2.0, 4.0]


@pytest.mark.parametrize(
    ("given", "told"),
    [
        (
            "0=3:1",
            r"bounds of dimension 0 \(x0\): 3 to 1 is not a range to draw; give finite LOW below HIGH, "
            r"e.g. bounds=\{0: \(1, 3\)\} \(avq plot --bounds 0=1:3\)",
        ),
        ("1=2:2", r"bounds of dimension 1 \(x1\): 2 to 2 is not a range.*\(avq plot --bounds 1=-3:3\)"),
        ("1=0:inf", r"bounds of dimension 1 \(x1\): 0 to inf is not a range.*\(avq plot --bounds 1=-3:3\)"),
    ],
)
def test_given_bounds_that_are_not_a_range_are_named_with_the_fix(given, told):
    agent = HandCells([(0.0, 0.0), (2.0, 2.0)], actions=[0, 1])
    with pytest.raises(ValueError, match=told):
        policy_map(agent, bounds=given, resolution=4)


def test_borders_are_drawn_between_pixels_of_different_cells():
    from avq.plotting.policy import border_segments

    xs = ys = np.array([0.5, 1.5, 2.5, 3.5])
    segments = border_segments(np.array(THREE_CELLS), xs, ys)
    # Vertical: x = 2 from y 0 to 2 (cells 0 | 1), x = 1 from 2 to 3 (0 | 2), x = 3 from 2 to 3 (2 | 1);
    # horizontal: y = 2 from x 1 to 3 (0, 1 | 2), y = 3 at x 0 to 1 (0 | 2) and 3 to 4 (1 | 2).
    as_tuples = sorted(tuple(map(tuple, s)) for s in segments)
    assert as_tuples == sorted(
        [
            ((1.0, 2.0), (1.0, 3.0)),
            ((2.0, 0.0), (2.0, 2.0)),
            ((3.0, 2.0), (3.0, 3.0)),
            ((1.0, 2.0), (3.0, 2.0)),
            ((0.0, 3.0), (1.0, 3.0)),
            ((3.0, 3.0), (4.0, 3.0)),
        ]
    )


# -- seeds that never learned ---------------------------------------------------------------------------------


def _returns():
    """Four seeds of 100 episodes: two learn (-200 -> -100), one stays at -200, one only wanders about -150."""
    ramp = np.linspace(-200, -100, 100)
    return [ramp - 10.0, ramp + 2.0, np.full(100, -200.0), -150 + 5 * np.sin(np.arange(100.0))]


def test_seeds_that_never_learned_are_counted_by_the_stated_rule():
    runs = _returns()
    assert never_learned(runs, higher_is_better=True).tolist() == [False, False, True, True]
    # Read as steps (lower is better) the learners are the ones that got worse.
    assert never_learned(runs, higher_is_better=False).tolist() == [True, True, True, True]
    # A success level: the mean of the last tenth (episodes 91-100) must reach it. The ramp's last ten values
    # average -100 - 4.5 * 100 / 99 = -104.5, so seed 0's is -114.5 and seed 1's -102.5; seed 3's is about -150.
    assert never_learned(runs, higher_is_better=True, success=-110).tolist() == [True, False, True, True]
    assert never_learned(runs, higher_is_better=True, success=-160).tolist() == [False, False, True, False]
    assert never_learned(runs, higher_is_better=True, success=-100).tolist() == [True, True, True, True]
    # A gain smaller than a tenth of the line's spread does not count: 0 -> 5 when another seed goes 0 -> 100.
    small = [np.r_[np.zeros(50), np.full(50, 5.0)], np.r_[np.zeros(50), np.full(50, 100.0)]]
    assert never_learned(small, higher_is_better=True).tolist() == [True, False]
    assert never_learned([np.array([1.0])]).tolist() == [False]  # one episode: not judged


def test_the_curves_draw_seeds_that_never_learned_dashed_and_say_how_many():
    import matplotlib.pyplot as plt

    fig = learning_curves_figure({"avq": _returns()}, window=1, higher_is_better=True)
    ax = fig.axes[0]
    dashed = [line for line in ax.lines if line.get_linestyle() not in ("-", "None")]
    assert len(dashed) == 2  # the two seeds, each a line of its own
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [
        "avq (4 seeds; 2 never learned: dashed, not in the mean)"
    ]
    mean = [line for line in ax.lines if line.get_linewidth() == 1.8][0]
    assert np.allclose(mean.get_ydata(), (_returns()[0] + _returns()[1]) / 2)  # the mean of the two that learned
    assert "dashed: a seed that never learned" in ax.get_title()
    plt.close(fig)
    fig = learning_curves_figure({"random": [np.full(50, -200.0)] * 2}, higher_is_better=True)
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["random (2 seeds, none learned: each dashed)"]
    plt.close(fig)
