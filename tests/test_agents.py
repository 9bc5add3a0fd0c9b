"""The agents' API: parameters, seeding, additive learn, predict, records, saving; tabular Sarsa(λ)."""

import gymnasium as gym
import numpy as np
import pytest

import avq
from avq import AVQSarsa, TabularSarsa, evaluate_maze, make_agent


def maze(layout="lau2002", **kw):
    return gym.make("avq/GridMaze-v0", layout=layout, **kw)


def state_of(agent):
    return (agent.codebook_ if hasattr(agent, "codebook_") else agent.states_), agent.q_


@pytest.mark.parametrize("name", ["avq-paper", "tabular"])
def test_same_seed_same_result_and_different_seed_differs(name):
    a = make_agent(name, maze(), seed=7).learn(total_episodes=60)
    b = make_agent(name, maze(), seed=7).learn(total_episodes=60)
    c = make_agent(name, maze(), seed=8).learn(total_episodes=60)
    for x, y in zip(state_of(a), state_of(b)):
        assert np.array_equal(x, y)
    assert a.episode_history()["steps"].tolist() == b.episode_history()["steps"].tolist()
    assert a.episode_history()["steps"].tolist() != c.episode_history()["steps"].tolist()


@pytest.mark.parametrize("name", ["avq-paper", "tabular"])
@pytest.mark.parametrize("unit", ["total_episodes", "total_timesteps"])
def test_learn_is_additive(name, unit):
    n = 50 if unit == "total_episodes" else 2345
    whole = make_agent(name, maze(), seed=3).learn(**{unit: 2 * n + 1})
    parts = make_agent(name, maze(), seed=3)
    parts.learn(**{unit: n}).learn(**{unit: 1}).learn(**{unit: n})
    for x, y in zip(state_of(whole), state_of(parts)):
        assert np.array_equal(x, y)
    assert whole.num_timesteps == parts.num_timesteps and whole.num_episodes == parts.num_episodes


def test_timestep_budget_is_exact_and_can_stop_inside_an_episode():
    agent = make_agent("avq-paper", maze(), seed=0).learn(total_timesteps=150)
    assert agent.num_timesteps == 150
    assert sum(agent.episode_history()["steps"]) <= 150


def test_episode_records_and_callback_can_stop():
    seen = []

    def cb(agent, record):
        seen.append(record)
        return len(seen) < 5

    agent = make_agent("avq-paper", maze(), seed=0).learn(total_episodes=100, callback=cb)
    assert agent.num_episodes == 5 and len(seen) == 5
    h = agent.episode_history()
    assert set(h) >= {"episode", "steps", "return", "n_cells", "appends", "merges", "decisions", "wall_s"}
    assert h["episode"].tolist() == [1, 2, 3, 4, 5]
    assert h["n_cells"][-1] == agent.n_cells
    assert h["steps"].sum() == agent.num_timesteps
    assert all(1 <= s <= 100 for s in h["steps"])


def test_predict_single_and_batch_and_queries_do_not_change_state():
    agent = make_agent("avq-paper", maze(), seed=0).learn(total_episodes=30)
    before = state_of(agent)
    rng_state = agent._rng.bit_generator.state
    obs = np.array([[1, 1], [12, 8], [5, 9]], dtype=np.float32)
    batch, none = agent.predict(obs)
    assert none is None and batch.shape == (3,)
    singles = [agent.predict(o)[0] for o in obs]
    assert batch.tolist() == singles and all(isinstance(a, int) for a in singles)
    cells = agent.cells(obs)
    assert batch.tolist() == agent.q_[cells].argmax(axis=1).tolist()
    agent.predict(obs, deterministic=False)
    for x, y in zip(before, state_of(agent)):
        assert np.array_equal(x, y)
    assert agent._rng.bit_generator.state == rng_state
    with pytest.raises(ValueError, match="shape"):
        agent.predict(np.zeros(3))


def test_predict_before_learn_is_a_clear_error():
    with pytest.raises(RuntimeError, match="learn"):
        make_agent("avq-paper", maze()).predict(np.zeros(2))


@pytest.mark.parametrize("name", ["avq-paper", "tabular"])
def test_save_load_round_trip_is_exact(tmp_path, name):
    agent = make_agent(name, maze(), seed=1).learn(total_episodes=40)
    path = agent.save(tmp_path / "model")
    assert path.suffix == ".zip"
    loaded = avq.load(path, env=maze())
    for x, y in zip(state_of(agent), state_of(loaded)):
        assert np.array_equal(x, y)
    assert loaded.get_params() == agent.get_params()
    obs = maze().unwrapped.layout.free_positions().astype(float)
    assert np.array_equal(agent.predict(obs)[0], loaded.predict(obs)[0])
    assert type(loaded).load(path).num_timesteps == agent.num_timesteps  # env made from the stored id


def test_load_refuses_foreign_and_mismatched_files(tmp_path):
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="bad.zip"):
        avq.load(bad)
    agent = make_agent("avq-paper", maze(), seed=1).learn(total_episodes=3)
    path = agent.save(tmp_path / "m.zip")
    with pytest.raises(ValueError, match="observation_space"):
        avq.load(path, env=maze(layout="open5"))
    with pytest.raises(ValueError, match="not a TabularSarsa"):
        TabularSarsa.load(path)


@pytest.mark.parametrize(
    "param,value,match",
    [
        ("alpha", 0.0, r"alpha must be in \(0.0, 1.0\]"),
        ("alpha", 1.5, "alpha"),
        ("lam", -0.1, "lam"),
        ("gamma", 1.1, "gamma"),
        ("epsilon", 2, "epsilon"),
        ("d_min", -1, "d_min"),
        ("rho", -0.5, "rho"),
        ("chi", 1.0, "chi"),
        ("chi", 0.0, "chi"),
        ("q_init", float("nan"), "q_init"),
        ("traces", "dutch", "traces"),
        ("merge_every", -1, "merge_every"),
        ("merge_every", 1.5, "merge_every"),
        ("value_trigger", 0.0, "value_trigger"),
        ("seed", -3, "seed"),
        ("alpha", "0.1", "alpha"),
        ("max_cells", 0, "max_cells"),
        ("scale", [1.0, 0.0], "scale"),
    ],
)
def test_bad_parameters_name_the_parameter(param, value, match):
    with pytest.raises(ValueError, match=match):
        AVQSarsa(maze(), **{param: value})


def test_get_params_reads_the_signature():
    agent = make_agent("avq-paper", maze(), seed=4, alpha=0.3)
    p = agent.get_params()
    assert p["alpha"] == 0.3 and p["seed"] == 4 and p["lam"] == 0.7
    assert set(p) == set(AVQSarsa._param_names())


def test_make_agent_errors():
    with pytest.raises(ValueError, match="unknown agent 'nope'"):
        make_agent("nope", maze())
    with pytest.raises(ValueError, match="unknown parameter 'alpah'"):
        make_agent("avq-paper", maze(), alpah=0.1)


def test_avq_refuses_a_discrete_observation_space_and_points_to_tabular():
    with pytest.raises(ValueError, match="tabular"):
        AVQSarsa(gym.make("FrozenLake-v1"))


def test_avq_scale_from_bounds_and_unbounded_dimension_error():
    agent = AVQSarsa(maze(), seed=0)
    assert agent._scale.tolist() == [13.0, 11.0]
    with pytest.raises(ValueError, match="dimension 1"):
        AVQSarsa(gym.make("CartPole-v1"), scale=None)
    AVQSarsa(gym.make("CartPole-v1"), scale=[1.0, 1.0, 1.0, 1.0])
    AVQSarsa(gym.make("CartPole-v1"))  # scale="auto": estimated for the unbounded dimensions
    with pytest.raises(
        ValueError, match="scale must be 'auto', 'spread', None, a number > 0 or one per dimension, not 'atuo'"
    ):
        AVQSarsa(gym.make("CartPole-v1"), scale="atuo")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tabular_finds_the_shortest_path_on_a_small_maze(seed):
    layout = ["S...#", ".##.#", "....G", ".#...", "....."]
    # Enough exploration (epsilon 0.3) that no action is left untried; gamma 0.95 rewards short paths.
    agent = TabularSarsa(maze(layout), alpha=0.2, gamma=0.95, epsilon=0.3, seed=seed).learn(total_episodes=2000)
    res = evaluate_maze(agent, maze(layout))
    assert res["success_rate"] == 1.0
    assert res["path_ratio"] == 1.0
    assert all(o["steps"] == o["shortest"] for o in res["outcomes"])


def test_tabular_on_a_discrete_observation_space():
    env = gym.make("FrozenLake-v1", is_slippery=False)
    agent = TabularSarsa(env, alpha=0.5, gamma=0.9, epsilon=0.2, seed=0).learn(total_episodes=300)
    assert agent.q_.shape[1] == 4
    obs, _ = env.reset(seed=0)
    steps, done = 0, False
    while not done and steps < 20:
        a, _ = agent.predict(obs)
        obs, r, done, trunc, _ = env.step(a)
        steps += 1
    assert r == 1.0 and steps == 6


def test_evaluate_maze_by_hand_on_a_corridor():
    # In the corridor #S...G# every position's best action must be East once learned.
    env = maze("corridor")
    agent = TabularSarsa(env, seed=0).learn(total_episodes=200)
    res = evaluate_maze(agent, maze("corridor"))
    assert [o["start"] for o in res["outcomes"]] == [(1, 1), (2, 1), (3, 1), (4, 1)]
    assert [o["shortest"] for o in res["outcomes"]] == [4, 3, 2, 1]
    assert res["success_rate"] == 1.0 and res["path_ratio"] == 1.0


def test_evaluate_maze_counts_failures_and_path_ratio():
    class AlwaysWest:
        def predict(self, obs, deterministic=True):
            return 3, None

    res = evaluate_maze(AlwaysWest(), maze("corridor"))
    assert res["success_rate"] == 0.0 and res["path_ratio"] is None
    assert all(o["steps"] == 100 for o in res["outcomes"])


@pytest.mark.parametrize("name", ["avq-paper", "avq", "tabular"])
def test_a_loaded_agent_keeps_learning_reproducibly(tmp_path, name):
    agent = make_agent(name, maze(), seed=1).learn(total_episodes=7)
    path = agent.save(tmp_path / "m.zip")
    runs = [avq.load(path).learn(total_episodes=5) for _ in range(2)]
    assert runs[0].num_episodes == 12
    for x, y in zip(state_of(runs[0]), state_of(runs[1])):
        assert np.array_equal(x, y)


def test_predict_refuses_non_finite_and_info_pairs():
    agent = make_agent("avq-paper", maze(), seed=0).learn(total_episodes=2)
    with pytest.raises(ValueError, match="NaN or infinite"):
        agent.predict(np.array([np.nan, 1.0]))
    with pytest.raises(ValueError, match="observation alone"):
        agent.predict(maze().reset(seed=0))
    with pytest.raises(ValueError, match="deterministic"):
        agent.predict(np.zeros(2), deterministic="no")
    tab = TabularSarsa(gym.make("FrozenLake-v1"), seed=0).learn(total_episodes=2)
    with pytest.raises(ValueError, match="not in the observation space"):
        tab.predict(99)


def test_saved_files_have_ordinary_permissions(tmp_path):
    import os

    old = os.umask(0o022)
    try:
        path = make_agent("tabular", maze(), seed=0).learn(total_episodes=1).save(tmp_path / "m.zip")
    finally:
        os.umask(old)
    assert os.stat(path).st_mode & 0o777 == 0o644


def test_load_names_a_space_mismatch_before_anything_else(tmp_path):
    path = make_agent("avq-paper", maze(), seed=0).learn(total_episodes=1).save(tmp_path / "m.zip")
    with pytest.raises(ValueError, match="whose observation_space is Box"):
        avq.load(path, env=gym.make("CartPole-v1"))


def test_evaluate_maze_refuses_an_agent_trained_on_another_layout_as_load_does(tmp_path):
    agent = make_agent("avq-paper", maze(), seed=0).learn(total_episodes=5)
    with pytest.raises(ValueError) as evaluating:
        evaluate_maze(agent, maze("open5"))
    with pytest.raises(ValueError) as loading:
        avq.load(agent.save(tmp_path / "m.zip"), env=maze("open5"))
    told = (
        "the agent was trained on avq/GridMaze-v0 with layout='lau2002', max_episode_steps=100, whose "
        "observation_space is Box(low=[0.0, 0.0], high=[13.0, 11.0]), but env's is Box(low=[0.0, 0.0], "
        "high=[4.0, 4.0]); pass an environment made like the one it was trained on (the same id and "
        "gymnasium.make arguments: on a maze, the same layout)"
    )
    assert str(evaluating.value) == f"evaluate_maze: {told}"
    assert str(loading.value) == f"{tmp_path / 'm.zip'}: {told}"
    assert evaluate_maze(agent, maze())["success_rate"] >= 0.0  # its own layout is accepted


@pytest.mark.parametrize("name", ["avq", "tabular", "grid", "tiles"])
@pytest.mark.parametrize(
    ("bad_step", "where"),
    [
        (((np.nan, 1.0), -1.0, False, False, False), "observation"),
        (((1.0, -np.inf), -1.0, False, False, False), "observation"),
        (((1.0, 1.0), np.inf, False, False, False), "reward"),
        (((1.0, 1.0), np.nan, False, False, False), "reward"),
    ],
)
def test_every_agent_names_the_step_of_a_non_finite_observation_or_reward(scripted, name, bad_step, where):
    good = ((1.0, 0.0), -1.0, False, False, False)
    env = scripted([((0.0, 0.0), [good, good, bad_step, good])])
    agent = make_agent(name, env, seed=0)
    with pytest.raises(ValueError, match=rf"{where} .* at step 3 of episode 1 is not finite"):
        agent.learn(total_episodes=1)
    arrays = agent._state_dict()[1]
    assert all(np.isfinite(a).all() for a in arrays.values())


@pytest.mark.parametrize("name", ["avq", "tabular", "grid", "tiles"])
def test_every_agent_refuses_a_non_finite_first_observation(scripted, name):
    env = scripted([((np.nan, 0.0), [((1.0, 0.0), -1.0, True, False, False)])])
    with pytest.raises(ValueError, match="at step 0 of episode 1 is not finite"):
        make_agent(name, env, seed=0).learn(total_episodes=1)


def test_epsilon_schedule_decays_per_episode_to_its_floor_and_survives_loading(tmp_path):
    from avq.agents.avq_sarsa import kernels as core

    agent = make_agent("avq-maze", maze(), seed=0, epsilon=0.4, epsilon_decay=0.5, epsilon_min=0.06)
    seen = []
    agent.learn(total_episodes=4, callback=lambda a, r: seen.append(float(a._P[core.FloatParam.EPSILON_NOW])))
    assert seen == pytest.approx([0.2, 0.1, 0.06, 0.06], rel=1e-12)  # 0.4 * 0.5**k, floored at 0.06
    loaded = avq.load(agent.save(tmp_path / "m.zip"))
    assert loaded._P[core.FloatParam.EPSILON_NOW] == agent._P[core.FloatParam.EPSILON_NOW]
    fused = make_agent("avq-maze", maze(), seed=3, epsilon_decay=0.98).learn(total_episodes=60)
    generic = make_agent("avq-maze", maze(), seed=3, epsilon_decay=0.98, fused=False).learn(total_episodes=60)
    assert np.array_equal(fused.q_, generic.q_) and np.array_equal(fused.codebook_, generic.codebook_)
    for bad in ({"epsilon_decay": 0.0}, {"epsilon_decay": 1.5}, {"epsilon_min": -0.1}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            make_agent("avq", maze(), **bad)


def test_alpha_schedule_decays_per_episode_and_is_the_step_of_the_updates(tmp_path):
    from avq.agents.avq_sarsa import kernels as core

    agent = make_agent("avq-maze", maze(), seed=0, alpha=0.8, alpha_decay=0.5, alpha_min=0.15)
    seen = []
    agent.learn(total_episodes=4, callback=lambda a, r: seen.append(float(a._P[core.FloatParam.ALPHA_NOW])))
    assert seen == pytest.approx([0.4, 0.2, 0.15, 0.15], rel=1e-12)  # 0.8 * 0.5**k, floored at 0.15
    assert agent.alpha == 0.8  # the parameter itself is untouched
    loaded = avq.load(agent.save(tmp_path / "m.zip"))
    assert loaded._P[core.FloatParam.ALPHA_NOW] == agent._P[core.FloatParam.ALPHA_NOW]
    # The scheduled step is the one used: a constant alpha of 0.4 for episode 2 gives the same values as
    # a schedule that is at 0.4 then (0.8 after one episode of alpha 0.8 ... compared on whole runs).
    fused = make_agent("avq-maze", maze(), seed=3, alpha_decay=0.98).learn(total_episodes=60)
    generic = make_agent("avq-maze", maze(), seed=3, alpha_decay=0.98, fused=False).learn(total_episodes=60)
    constant = make_agent("avq-maze", maze(), seed=3).learn(total_episodes=60)
    assert np.array_equal(fused.q_, generic.q_) and np.array_equal(fused.codebook_, generic.codebook_)
    assert not np.array_equal(fused.episode_history()["steps"], constant.episode_history()["steps"])
    for bad in ({"alpha_decay": 0.0}, {"alpha_decay": 1.5}, {"alpha_min": -0.1}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            make_agent("avq", maze(), **bad)


def test_avq_has_maze_defaults_on_the_mazes_and_general_defaults_elsewhere():
    from avq.agents.registry import AGENTS, DEFAULTS, agent_class, agent_defaults

    maze = avq.make_agent("avq", gym.make("avq/GridMaze-v0"), seed=0)
    # On both mazes: the planning agent of avq-plan's maze entries, merging under its model; on the grid maze a
    # decision never tried near the current square is also tried while learning (known_radius).
    assert maze.get_params() == {
        **avq.make_agent("avq-plan", "avq/GridMaze-v0").get_params(),
        "rho": 25.0,
        "known_radius": 0.3,
        "seed": 0,
    }
    from avq.envs import GridMaze

    assert avq.make_agent("avq", GridMaze(), seed=0).get_params() == maze.get_params()  # built without gym.make
    robot = avq.make_agent("avq", "avq/RobotMaze-v0")
    assert isinstance(maze, avq.PlanningAVQ) and isinstance(robot, avq.PlanningAVQ)
    assert robot.get_params() == {
        **avq.make_agent("avq-plan", "avq/RobotMaze-v0").get_params(),
        "rho": 25.0,
    }
    general = avq.make_agent("avq", gym.make("MountainCar-v0"))
    assert isinstance(general, avq.PlanningAVQ) and agent_class("avq", "MountainCar-v0") is avq.PlanningAVQ
    assert {k: general.get_params()[k] for k in AGENTS["avq"][1]} == AGENTS["avq"][1]
    assert general.split_after == 5 and general.v_opt == "auto"
    assert AGENTS["avq"][1] == DEFAULTS["avq-plan"]["*"]  # (one set of general defaults for the planning agent)
    # Explicit overrides win over the task's defaults; the task's defaults replace all of the name's.
    assert avq.make_agent("avq", "avq/GridMaze-v0", cycle_split=True, d_min=0.01).get_params()["d_min"] == 0.01
    assert agent_defaults("avq", "avq/GridMaze-v0") == DEFAULTS["avq"]["avq/GridMaze-v0"]
    assert "merge_age" not in agent_defaults("avq", "avq/GridMaze-v0")  # (avq-maze's, not the planner's)
    assert agent_defaults("avq", "MountainCar-v0") == AGENTS["avq"][1]
    # CartPole-v1's entry is the general defaults with ε-greedy exploration on top of the optimism, and the pole's
    # dimensions twice as weighty as the cart's.
    assert agent_defaults("avq", "CartPole-v1") == {
        **AGENTS["avq"][1],
        "epsilon": 0.01,
        "scale_factor": [1.0, 1.0, 0.5, 0.5],
    }
    # Acrobot-v1's: every dimension's scale estimated, the four components of the angles a third as weighty,
    # untried decisions worth the return at which Gymnasium calls the task solved, and the cells' floor kept at d_min.
    acrobot = avq.make_agent("avq", "Acrobot-v1")
    assert agent_defaults("avq", "Acrobot-v1") == {
        **AGENTS["avq"][1],
        "scale": "spread",
        "scale_factor": [3.0, 3.0, 3.0, 3.0, 1.0, 1.0],
        "v_opt": gym.spec("Acrobot-v1").reward_threshold,
        "finer_when_settled": 0,
    }
    assert acrobot.v_opt_ == -100.0
    high = acrobot.env.observation_space.high.astype(np.float64)
    assert acrobot.scale_.tolist() == (2 * high * [3, 3, 3, 3, 1, 1]).tolist()  # (the bounds' range until estimated)
    with pytest.raises(ValueError, match="unknown agent 'nope'"):
        agent_defaults("nope")


def test_an_agent_whose_class_depends_on_the_task_names_the_task_and_class_in_its_errors(monkeypatch):
    # An entry of a defaults file may name its own class (`class:`); none of the package's does today, so the
    # grid maze's entry of avq is made the Sarsa(λ) maze agent's here.
    from avq.agents import registry

    maze_rules = registry.ENTRIES["avq-maze"]["*"]
    monkeypatch.setitem(registry.ENTRIES["avq"], "avq/GridMaze-v0", maze_rules)
    monkeypatch.setitem(registry.DEFAULTS["avq"], "avq/GridMaze-v0", maze_rules.params)
    assert isinstance(make_agent("avq", "avq/GridMaze-v0"), AVQSarsa)
    with pytest.raises(ValueError, match=r"^unknown parameter 'alpha' for agent 'avq' on MountainCar-v0 \(class Pl"):
        make_agent("avq", "MountainCar-v0", alpha=0.2)
    with pytest.raises(
        ValueError,
        match="agent 'avq' has no model on avq/GridMaze-v0; "
        "the agents that plan on avq/GridMaze-v0 are 'avq-plan', 'grid-ps', 'tabular-ps'$",
    ):
        make_agent("avq", "avq/GridMaze-v0", n_backups=10)


def test_make_agent_records_which_defaults_it_used_and_get_params_shows_the_values_in_force():
    from avq.agents.registry import AGENTS, DEFAULTS, defaults_key

    maze = make_agent("avq", "avq/GridMaze-v0", seed=0)
    used = maze.defaults_used
    assert (used.name, used.env_id, used.key, used.explicit) == ("avq", "avq/GridMaze-v0", "avq/GridMaze-v0", {})
    assert str(used) == (
        "agent avq on avq/GridMaze-v0: the avq/GridMaze-v0 defaults of avq "
        "(avq/agents/defaults/avq.yaml, entry 'avq/GridMaze-v0'); explicit: none"
    )
    entry = DEFAULTS["avq"]["avq/GridMaze-v0"]
    assert {k: maze.get_params()[k] for k in entry} == entry
    general = make_agent("avq", "MountainCar-v0", d_min=0.2)
    assert general.defaults_used.key == "*" and general.defaults_used.explicit == {"d_min": 0.2}
    assert str(general.defaults_used).endswith("(avq/agents/defaults/avq.yaml, entry '*'); explicit: d_min=0.2")
    assert general.get_params()["d_min"] == 0.2 and general.get_params()["split_after"] == 5
    # scale="auto" is kept as given; the scale in force (here the observation bounds') is scale_.
    space = general.env.observation_space
    assert general.get_params()["scale"] == "auto"
    assert np.array_equal(general.scale_, np.asarray(space.high, np.float64) - np.asarray(space.low, np.float64))
    # scale None: the observation bounds' range (lau2002: 13 x 11 squares), so d_min is a fraction of the maze.
    assert np.array_equal(maze.scale_, [13.0, 11.0]) and maze.get_params()["scale"] is None
    assert AVQSarsa("avq/GridMaze-v0").defaults_used is None  # built directly: the signature's defaults
    assert defaults_key("avq", "MountainCar-v0") == "*" and defaults_key("tabular", "avq/GridMaze-v0") == "*"
    assert defaults_key("avq", "CartPole-v1") == "CartPole-v1"
    # CartPole-v0 (the same cart and pole, 200 steps) takes CartPole-v1's entry.
    assert defaults_key("avq-plan", "CartPole-v0") == "CartPole-v0"
    assert DEFAULTS["avq"]["CartPole-v0"] == DEFAULTS["avq-plan"]["CartPole-v0"] == DEFAULTS["avq"]["CartPole-v1"]
    cartpole = make_agent("avq", gym.make("CartPole-v0"), seed=0)
    assert cartpole.get_params()["epsilon"] == 0.01 and cartpole.get_params()["scale_factor"] == [1.0, 1.0, 0.5, 0.5]
    # One table: AGENTS holds DEFAULTS' own "*" entries.
    for name, table in DEFAULTS.items():
        assert AGENTS[name][1] is table["*"]


def test_validators_name_the_parameter_and_the_value():
    from avq._validate import check_bool, check_choice, check_int, check_optional, check_range

    assert check_range("alpha", 1, 0.0, 1.0, low_open=True) == 1.0
    assert check_optional(check_int, "seed", None, 0) is None and check_optional(check_int, "seed", 3, 0) == 3
    for call, message in (
        (lambda: check_range("alpha", 0.0, 0.0, 1.0, low_open=True), r"alpha must be in \(0.0, 1.0\], not 0.0"),
        (lambda: check_range("rho", "x", 0.0, np.inf), r"rho must be a number in \[0.0, inf\], not 'x'"),
        (lambda: check_int("max_cells", True, 1), "max_cells must be an integer >= 1, not True"),
        (lambda: check_bool("fused", 1), "fused must be True or False, not 1"),
        (
            lambda: check_choice("traces", "x", ("replacing", "accumulating")),
            "traces must be 'replacing' or 'accumulating', not 'x'",
        ),
        (
            lambda: check_choice("merge_pairs", "x", ("a", "b", "c")),
            "merge_pairs must be one of 'a', 'b', 'c', not 'x'",
        ),
        (lambda: check_optional(check_int, "seed", -1, 0), "seed must be an integer >= 0 or None, not -1"),
    ):
        with pytest.raises(ValueError, match=message):
            call()


def test_the_defaults_files_resolve_bases_and_carry_a_reason_and_a_link(tmp_path):
    from importlib import resources

    import yaml

    from avq.agents.registry import DEFAULTS, ENTRIES

    folder = resources.files("avq.agents").joinpath("defaults")
    names = sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))
    assert names == sorted(DEFAULTS)  # one file per agent, and every file read
    for name in names:
        raw = yaml.safe_load(folder.joinpath(f"{name}.yaml").read_text(encoding="utf-8"))
        for key, entry in raw["entries"].items():
            resolved = ENTRIES[name][key]
            assert (
                resolved.reason.strip()
                and "#" in resolved.results
                and resolved.results.endswith(resolved.results.split("#")[1])
            )
            # base: the base entry's params, then the entry's own on top.
            if "base" in entry:
                base = DEFAULTS[entry["base"].get("agent", name)][entry["base"]["entry"]]
                assert resolved.params == {**base, **(entry.get("params") or {})}
            else:
                assert resolved.params == entry["params"]
    # Written out: CartPole-v0 starts from CartPole-v1's entry, which adds two values to avq-plan's "*".
    assert DEFAULTS["avq-plan"]["CartPole-v0"] == {
        **DEFAULTS["avq-plan"]["*"],
        "epsilon": 0.01,
        "scale_factor": [1.0, 1.0, 0.5, 0.5],
    }
    assert ENTRIES["avq"]["avq/GridMaze-v0"].cls is avq.PlanningAVQ and ENTRIES["avq-maze"]["*"].cls is AVQSarsa
