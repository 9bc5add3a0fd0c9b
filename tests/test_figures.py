"""What the figures draw: greedy walks that fail, arrows on their own cells, running means, the
spread over seeds, the partition's animation, and `avq train --animate`."""

import re

import gymnasium as gym
import numpy as np
import pytest
from PIL import Image

import avq.envs  # noqa: F401  (registers the mazes)
from avq.agents.registry import make_agent
from avq.cli import main
from avq.evaluation import evaluate_maze
from avq.figure_data import PartitionRecorder, cell_anchors, greedy_walk, partition_view, sample_walks
from avq.plotting import animate_partition, learning_curves_figure, running_mean

N, E, S, W = 0, 1, 2, 3
SMALL = ["#######", "#....G#", "#.....#", "#######"]


class TablePolicy:
    """A greedy policy written by hand: ``actions[(x, y)]``."""

    def __init__(self, actions):
        self.actions = actions

    def predict(self, obs, deterministic=True):
        return self.actions[(int(obs[0]), int(obs[1]))], None


def small_maze():
    return gym.make("avq/GridMaze-v0", layout=SMALL)


# -- greedy walks ------------------------------------------------------------------------------------


def test_a_walk_into_a_wall_ends_at_the_bump_and_says_so():
    walk = greedy_walk(TablePolicy({(1, 1): E, (2, 1): N}), small_maze(), (1, 1))
    assert walk.outcome == "bump" and walk.steps == 2 and walk.bump_action == N
    assert walk.positions.tolist() == [[1, 1], [2, 1]]  # a bump does not move: (2, 1) is the last square


def test_a_walk_into_a_wall_from_the_start_still_has_its_start_and_direction():
    walk = greedy_walk(TablePolicy({(1, 1): W}), small_maze(), (1, 1))
    assert walk.outcome == "bump" and walk.steps == 1 and walk.bump_action == W
    assert walk.positions.tolist() == [[1, 1]]


def test_a_walk_round_a_loop_ends_where_the_loop_closes():
    square = {(1, 1): S, (1, 2): E, (2, 2): N, (2, 1): W, (3, 1): W}
    walk = greedy_walk(TablePolicy(square), small_maze(), (3, 1))
    assert walk.outcome == "loop" and walk.loop_from == 1 and walk.steps == 5
    assert walk.positions.tolist() == [[3, 1], [2, 1], [1, 1], [1, 2], [2, 2], [2, 1]]


def test_a_walk_to_the_goal_and_one_cut_by_the_limit():
    east = {(x, y): E for x in range(1, 6) for y in (1, 2)}
    walk = greedy_walk(TablePolicy(east), small_maze(), (1, 1))
    assert walk.outcome == "goal" and walk.steps == 4
    assert walk.positions.tolist() == [[1, 1], [2, 1], [3, 1], [4, 1], [5, 1]]
    slippery = gym.make("avq/GridMaze-v0", layout=SMALL, slip=0.5)  # random: no bump or loop ends the walk
    slippery.unwrapped.reset(seed=0)
    walk = greedy_walk(TablePolicy({**east, (5, 2): N, (1, 1): W}), slippery, (1, 1), max_steps=3)
    assert walk.outcome in ("goal", "limit") and walk.steps <= 3


def test_the_sample_walks_of_a_trained_agent_agree_with_evaluate_maze():
    env = gym.make("avq/GridMaze-v0", layout="lau2002")
    agent = make_agent("avq-paper", env, seed=0).learn(total_episodes=300)
    outcomes = {o["start"]: o for o in evaluate_maze(agent, gym.make("avq/GridMaze-v0", layout="lau2002"))["outcomes"]}
    walks = sample_walks(agent, gym.make("avq/GridMaze-v0", layout="lau2002"))
    assert [w.outcome == "goal" for w in walks] == [True, False]  # this seed reaches the goal from some starts only
    for walk in walks:
        start = tuple(int(v) for v in walk.positions[0])
        assert outcomes[start]["success"] == (walk.outcome == "goal")
        same = [o for o in outcomes.values() if o["success"] == outcomes[start]["success"]]
        assert outcomes[start]["shortest"] == max(o["shortest"] for o in same)
    assert walks[0].steps == outcomes[tuple(int(v) for v in walks[0].positions[0])]["steps"]
    assert walks[1].outcome in ("bump", "loop") and len(walks[1].positions) >= 1


# -- where the arrows go ---------------------------------------------------------------------------------


def test_each_cell_is_labelled_on_its_own_squares_once_per_connected_part():
    # cells by square (y down):   0 0 0 1
    #                             0 2 2 2
    #                             0 2 1 1
    squares = np.array([(x, y) for y in range(3) for x in range(4)])
    cells = np.array([0, 0, 0, 1, 0, 2, 2, 2, 0, 2, 1, 1])
    anchors = cell_anchors(squares, cells)
    # cell 0 is an L whose mean (0.6, 0.6) is nearest (1, 1), a square of cell 2: its anchor is its own
    # square nearest that mean, (1, 0) before (0, 1) on the tie; cell 1 has two parts, each labelled.
    assert anchors.tolist() == [[0, 1], [1, 3], [1, 10], [2, 6]]
    assert all(cells[i] == c for c, i in anchors)


def _anchors_by_labelling(squares, cells):
    """cell_anchors as it was first written: the grid labelled once per cell (scipy)."""
    from scipy.ndimage import label

    grid = np.full((squares[:, 1].max() + 1, squares[:, 0].max() + 1), -1)
    index = np.full(grid.shape, -1)
    grid[squares[:, 1], squares[:, 0]] = cells
    index[squares[:, 1], squares[:, 0]] = np.arange(len(squares))
    rows = []
    for c in np.unique(cells):
        parts, n_parts = label(grid == c)
        for part in range(1, n_parts + 1):
            own = index[parts == part]
            xy = squares[own].astype(float)
            rows.append((c, own[np.argmin(((xy - xy.mean(axis=0)) ** 2).sum(axis=1))]))
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def test_the_anchors_are_those_of_labelling_the_grid_once_per_cell():
    rng = np.random.default_rng(0)
    for case in range(300):
        h, w = rng.integers(1, 9, size=2)
        ys, xs = np.nonzero(rng.random((h, w)) < rng.uniform(0.3, 1.0))
        if len(xs) == 0:
            continue
        squares = np.stack([xs, ys], axis=1)
        if case % 3 == 0:  # squares in any order
            squares = squares[rng.permutation(len(squares))]
        cells = rng.integers(0, rng.integers(1, 6), size=len(squares))
        assert np.array_equal(cell_anchors(squares, cells), _anchors_by_labelling(squares, cells))


def test_the_arrows_of_a_trained_agent_lie_on_their_own_cells():
    env = gym.make("avq/GridMaze-v0", layout="lau2002")
    agent = make_agent("avq", env, seed=2).learn(total_episodes=300)  # (a seed where the case below arises)
    recorder = PartitionRecorder(gym.make("avq/GridMaze-v0", layout="lau2002"))
    view = partition_view(agent, recorder.maze)
    assert all(view.cells[i] == c for c, i in view.anchors)
    assert set(view.anchors[:, 0]) == set(view.cells)  # every cell that holds a square is labelled
    # The case of the figure: a codebook vector whose own squares do not include the square it lies on.
    nearest_square = [np.argmin(((view.squares - v) ** 2).sum(axis=1)) for v in view.vectors]
    assert any(view.cells[i] != c for c, i in enumerate(nearest_square))
    # The arrow is the cell's greedy action.
    for c, i in view.anchors:
        assert view.actions[i] == agent.q_[c].argmax()


# -- learning curves ------------------------------------------------------------------------------------


def test_the_running_mean_uses_whole_windows_only():
    trials, mean = running_mean([10, 0, 0, 0, 5, 5], 2)
    assert trials.tolist() == [2, 3, 4, 5, 6] and mean.tolist() == [5.0, 0.0, 0.0, 2.5, 5.0]
    trials, mean = running_mean(np.full(50, 7.0), 20)  # no padding pulls the start down
    assert trials[0] == 20 and np.all(mean == 7.0)
    trials, mean = running_mean([3, 1, 2], 1)
    assert trials.tolist() == [1, 2, 3] and mean.tolist() == [3, 1, 2]


@pytest.mark.parametrize("seeds,bands,thin", [(3, 0, 3), (5, 1, 0)])
def test_few_seeds_are_drawn_one_by_one_and_many_with_an_interval(seeds, bands, thin):
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    rng = np.random.default_rng(0)
    learning = np.linspace(150, 50, 200)  # steps per trial: every seed learns (none is drawn apart)
    curves = {
        "avq": [learning + rng.normal(0, 10, 200) for _ in range(seeds)],
        "tabular": [learning + rng.normal(0, 10, 200) for _ in range(seeds)],
    }
    cells = {"avq": [np.arange(200) // 10 for _ in range(seeds)]}
    fig = learning_curves_figure(curves, cells=cells)
    ax, ax2 = fig.axes
    assert sum(isinstance(c, PolyCollection) for c in ax.collections) == bands * 2
    assert len(ax.lines) == (thin + 1) * 2  # the seeds (thin) and the mean of each agent
    assert ax.lines[-1].get_xdata()[0] == 20  # the 20-trial mean starts at trial 20
    assert "not drawn: tabular" in ax2.get_title()
    assert ax.get_legend() is None and ax2.get_legend() is None and len(fig.legends) == 1  # off the data
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [f"avq ({seeds} seeds)", f"tabular ({seeds} seeds)"]
    plt.close(fig)


# -- the animation -----------------------------------------------------------------------------------------


def test_the_recorder_keeps_evenly_spaced_views_and_the_last_and_changes_nothing():
    env = gym.make("avq/GridMaze-v0", layout="lau2002")
    recorder = PartitionRecorder(gym.make("avq/GridMaze-v0", layout="lau2002"), max_frames=4)
    agent = make_agent("avq-paper", env, seed=1).learn(total_episodes=20, callback=recorder)
    views = recorder.views()
    # every: 1 -> 2 (at episode 6) -> 4 (at 10) -> 8 (at 20); the first view and the last are kept besides
    assert [v.episode for v in views] == [1, 8, 16, 20]
    plain = make_agent("avq-paper", gym.make("avq/GridMaze-v0", layout="lau2002"), seed=1).learn(total_episodes=20)
    assert np.array_equal(plain.codebook_, agent.codebook_) and np.array_equal(plain.q_, agent.q_)
    last = partition_view(plain, recorder.maze)
    assert np.array_equal(views[-1].cells, last.cells) and np.array_equal(views[-1].actions, last.actions)
    assert (
        views[0].n_cells
        == make_agent("avq-paper", gym.make("avq/GridMaze-v0", layout="lau2002"), seed=1)
        .learn(total_episodes=1)
        .n_cells
    )


def _same_views(a, b):
    return [v.episode for v in a] == [v.episode for v in b] and all(
        np.array_equal(x.cells, y.cells)
        and np.array_equal(x.actions, y.actions)
        and x.n_cells == y.n_cells
        and np.array_equal(x.vectors, y.vectors)
        for x, y in zip(a, b)
    )


def test_the_recorder_learning_in_chunks_keeps_the_views_a_separate_training_to_each_episode_gives():
    def maze():
        return gym.make("avq/GridMaze-v0", layout="lau2002")

    recorder = PartitionRecorder(maze(), max_frames=4)
    agent = recorder.learn(make_agent("avq-paper", maze(), seed=1), 20)
    views = recorder.views()
    assert agent.num_episodes == 20 and [v.episode for v in views] == [1, 8, 16, 20]
    assert recorder.every == 8
    # Each view is the partition of an agent of the same seed trained on its own up to that episode.
    for view in views:
        alone = make_agent("avq-paper", maze(), seed=1).learn(total_episodes=view.episode)
        expected = partition_view(alone, recorder.maze)
        assert view.n_cells == alone.n_cells == expected.n_cells
        assert np.array_equal(view.cells, expected.cells) and np.array_equal(view.actions, expected.actions)
        assert np.array_equal(view.vectors, alone.codebook_[:, :2])
    # The agent is the one learn gives in one call, and the views are those of the recorder as a callback.
    plain = make_agent("avq-paper", maze(), seed=1).learn(total_episodes=20)
    assert np.array_equal(plain.codebook_, agent.codebook_) and np.array_equal(plain.q_, agent.q_)
    assert plain.num_timesteps == agent.num_timesteps
    assert np.array_equal(plain.episode_history()["steps"], agent.episode_history()["steps"])
    called = PartitionRecorder(maze(), max_frames=4)
    make_agent("avq-paper", maze(), seed=1).learn(
        total_episodes=20, callback=lambda a, r: called(a, r)
    )  # every episode
    assert _same_views(views, called.views())


@pytest.mark.parametrize("max_frames,chunks", [(4, [7, 13]), (3, [1, 0, 5, 30]), (100, [12, 300])])
def test_the_recorder_learning_in_chunks_goes_on_as_the_callback_does(max_frames, chunks):
    def maze():
        return gym.make("avq/GridMaze-v0", layout=SMALL)

    recorder = PartitionRecorder(maze(), max_frames=max_frames)
    agent = make_agent("avq", maze(), seed=3)
    for n in chunks:
        recorder.learn(agent, n)
    called = PartitionRecorder(maze(), max_frames=max_frames)
    other = make_agent("avq", maze(), seed=3).learn(total_episodes=sum(chunks), callback=lambda a, r: called(a, r))
    assert recorder.every == called.every
    assert _same_views(recorder.views(), called.views())
    assert np.array_equal(agent.q_, other.q_) and np.array_equal(agent.codebook_, other.codebook_)


def test_the_gif_has_one_frame_per_view(tmp_path):
    env = gym.make("avq/GridMaze-v0", layout="lau2002")
    recorder = PartitionRecorder(gym.make("avq/GridMaze-v0", layout="lau2002"))
    make_agent("avq", env, seed=0).learn(total_episodes=12, callback=recorder)
    views = recorder.views()
    assert [v.episode for v in views] == list(range(1, 13))
    path = animate_partition(views, recorder.env, tmp_path / "p.gif", title="avq")
    with Image.open(path) as gif:
        assert gif.format == "GIF" and gif.n_frames == 12


def test_a_gif_frame_keeps_its_255_most_frequent_colours_and_takes_the_nearest_for_the_others():
    from avq.plotting.animation import _palette_image

    kept = np.stack([np.arange(255) * 1, 255 - np.arange(255), np.arange(255) * 7 % 256], axis=1)
    exact = np.repeat(kept, 2, axis=0).reshape(17, 30, 3).astype(np.uint8)  # 255 colours, 2 pixels each
    image = _palette_image(Image.fromarray(exact))
    assert image.mode == "P" and np.array_equal(np.asarray(image.convert("RGB")), exact)
    assert len(image.getpalette()) <= 255 * 3  # an entry is left free (Pillow's transparent pixels)
    rare = np.clip(kept[::25] + [1, -2, 1], 0, 255)  # 11 more colours, on 1 pixel each, near 11 of those
    rgb = np.concatenate([exact.reshape(-1, 3), rare, kept[:1]]).reshape(1, -1, 3).astype(np.uint8)
    back = np.asarray(_palette_image(Image.fromarray(rgb)).convert("RGB"))
    assert np.array_equal(back[0, :510], exact.reshape(-1, 3))
    assert np.array_equal(back[0, 510:521], kept[::25])  # each rare colour as the colour it is nearest
    assert np.array_equal(back[0, 521], kept[0])


def test_a_frame_gives_the_same_palette_image_as_rgb_or_rgba_whatever_its_alpha_and_with_a_shared_table():
    from avq.plotting.animation import _palette_image

    rng = np.random.default_rng(0)
    colours = rng.integers(0, 256, size=(300, 3))  # more than 255: some go to their nearest
    rgb = colours[rng.integers(0, 300, size=(40, 50))].astype(np.uint8)
    alpha = rng.integers(0, 256, size=(40, 50, 1)).astype(np.uint8)
    want = _palette_image(Image.fromarray(rgb))
    table = np.zeros(1 << 24, dtype=np.uint8)
    _palette_image(np.roll(rgb, 7, axis=1), table)  # (another frame first, through the same table)
    for frame in (rgb, np.concatenate([rgb, alpha], axis=2), np.concatenate([rgb, 255 + 0 * alpha], axis=2)):
        got = _palette_image(frame, table)
        assert got.getpalette() == want.getpalette() and np.array_equal(np.asarray(got), np.asarray(want))


def _figure_with_what_a_crop_must_keep():
    from avq.plotting._figure import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(6, 3))
    for ax in axes:
        ax.plot([0, 1, 2], [2, 0, 1], label="a line")
        ax.set_title("a title\non two lines")
        ax.set_ylabel("a label")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.15))  # (below the axes)
    fig.tight_layout()
    fig.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0))  # (below the figure, as the learning curves')
    return plt, fig


def test_a_png_is_saved_with_the_size_and_pixels_of_savefigs_tight_crop(tmp_path):
    from avq.plotting._figure import save_figure

    plt, fig = _figure_with_what_a_crop_must_keep()
    fig.savefig(tmp_path / "savefig.png", dpi=150, bbox_inches="tight")
    plt.close(fig)
    plt, fig = _figure_with_what_a_crop_must_keep()
    save_figure(fig, tmp_path / "ours.png")
    plt.close(fig)
    with Image.open(tmp_path / "savefig.png") as want, Image.open(tmp_path / "ours.png") as got:
        assert got.mode == "RGB" and got.size == want.size and got.info["dpi"] == want.info["dpi"]
        assert np.array_equal(np.asarray(got), np.asarray(want.convert("RGB")))


def test_train_animate_writes_the_gif_on_both_mazes(tmp_path, capsys):
    out = tmp_path / "grid"
    assert (
        main(
            [
                "train",
                "--env",
                "avq/GridMaze-v0",
                "--agent",
                "avq-paper",
                "--episodes",
                "15",
                "--out",
                str(out),
                "--animate",
                "--no-progress",
            ]
        )
        == 0
    )
    assert f"wrote {out / 'partition.gif'} (15 frames)" in capsys.readouterr().out
    with Image.open(out / "partition.gif") as gif:
        assert gif.n_frames == 15
    out = tmp_path / "robot"
    assert (
        main(["train", "--env", "avq/RobotMaze-v0", "--episodes", "3", "--out", str(out), "--animate", "--no-progress"])
        == 0
    )
    with Image.open(out / "partition.gif") as gif:
        assert gif.n_frames == 3


@pytest.mark.parametrize(
    "args,needle",
    [
        (
            ["--env", "CartPole-v1"],
            "--animate draws the partition of a maze (avq/GridMaze-v0 or avq/RobotMaze-v0), not of CartPole-v1",
        ),
        (["--env", "avq/GridMaze-v0", "--agent", "tabular"], "--animate draws an agent's cells, and tabular has none"),
    ],
)
def test_train_animate_refuses_what_has_no_partition(tmp_path, capsys, args, needle):
    out = tmp_path / "run"
    assert main(["train", *args, "--episodes", "5", "--out", str(out), "--animate", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()  # refused before anything was written


def test_train_animate_is_not_for_resume(tmp_path, capsys):
    assert main(["train", "--resume", str(tmp_path), "--animate"]) == 2
    assert "drop --animate" in capsys.readouterr().err


# Slow (two reproductions); the fast run keeps the GIF of avq train --animate on both mazes.
@pytest.mark.slow
def test_reproduce_animates_the_headline_agent_unless_asked_not_to(tmp_path, capsys):
    out = tmp_path / "rep"
    args = ["reproduce", "--seeds", "2", "--trials", "15", "--agents", "avq-paper,tabular", "--no-progress"]
    assert main(args + ["--out", str(out)]) == 0
    assert re.search(rf"wrote {re.escape(str(out))}: .*partition\.gif", capsys.readouterr().out)
    with Image.open(out / "partition.gif") as gif:
        assert gif.n_frames == 15
    assert main(args + ["--out", str(tmp_path / "still"), "--no-animation"]) == 0
    assert (tmp_path / "still" / "partition.png").exists() and not (tmp_path / "still" / "partition.gif").exists()
