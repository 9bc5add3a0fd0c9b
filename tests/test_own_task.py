"""A user's own task: an environment registered by a module of the working directory, named as Gymnasium's
``module:id``, trained and evaluated from the command line (in a new process, as a user runs it) and from the
API; a module that cannot be imported is named with the fix; run names are valid file names everywhere.

The environment is the how-to's (docs/how-to/own-task.md), so that the page's code is the code tested."""

from __future__ import annotations

import functools
import importlib.util
import json
import re
import sys
from pathlib import Path

import gymnasium as gym
import pytest

import avq
from avq._io import file_name_part
from avq.envs import recorded_env_id
from avq.runs import default_run_dir

from conftest import cli_in_process, cli_subprocess

HOW_TO = Path(__file__).resolve().parents[1] / "docs" / "how-to" / "own-task.md"
#: The how-to's module: its first ```python block, which starts with the comment ``# nav3d.py: ...``.
NAV3D = re.search(r"^```python\n(# nav3d\.py.*?)^```", HOW_TO.read_text(encoding="utf-8"), re.M | re.S).group(1)


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    """A working directory holding ``nav3d.py`` (not on the Python path: avq must find it there), made the
    current directory; the module is forgotten afterwards, so that every test imports it afresh."""
    (tmp_path / "nav3d.py").write_text(NAV3D, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    yield tmp_path
    sys.modules.pop("nav3d", None)
    gym.registry.pop("user/Nav3D-v0", None)


def test_train_then_evaluate_an_env_of_a_module_in_the_working_directory(workdir):
    train = cli_subprocess("train", "--env", "nav3d:user/Nav3D-v0", "--episodes", "30", "--no-progress", cwd=workdir)
    assert train.returncode == 0, train.stderr
    (run,) = (workdir / "runs").iterdir()
    assert re.fullmatch(r"user-Nav3D-v0__avq__0__\d+", run.name)  # no ':' nor '/' from the id
    assert "avq on nav3d:user/Nav3D-v0 (seed 0): 30 episodes" in train.stdout

    for target in (run, run / "model.zip"):  # the model file records the module with the id: a new process finds it
        ev = cli_subprocess("evaluate", str(target.relative_to(workdir)), "--episodes", "3", "--json", cwd=workdir)
        assert ev.returncode == 0, ev.stderr
        report = json.loads(ev.stdout)
        assert (report["env"], report["agent"], report["class"], report["episodes"]) == (
            "user/Nav3D-v0",
            "avq",
            "PlanningAVQ",
            3,
        )


def test_a_module_that_is_not_there_is_named_with_the_fix(workdir):
    result = cli_subprocess("train", "--env", "nav3x:user/Nav3D-v0", "--episodes", "3", cwd=workdir)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.strip() == (
        f"avq: error: environment 'nav3x:user/Nav3D-v0': no module named 'nav3x' in the working directory {workdir} "
        "nor on the Python path; run avq from the directory that holds nav3x.py (or put that directory on "
        "PYTHONPATH), or correct the module's name before the ':'"
    )
    assert not (workdir / "runs").exists()


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("x = 1 / 0\n", "importing module 'broken' failed with ZeroDivisionError: division by zero ({path}, line 1)"),
        ("import no_such_dependency_of_avq\n", "it imports 'no_such_dependency_of_avq', which is not installed"),
        ("x = (\n", "importing module 'broken' failed with SyntaxError: '(' was never closed ({path}, line 1)"),
        ("", "unknown environment 'broken:user/Nav3D-v0' ("),
    ],
    ids=["raises", "missing-dependency", "syntax-error", "registers-nothing"],
)
def test_a_module_that_fails_to_import_or_to_register_is_named(workdir, source, expected):
    (workdir / "broken.py").write_text(source, encoding="utf-8")
    result = cli_in_process("train", "--env", "broken:user/Nav3D-v0", "--episodes", "3", cwd=workdir)
    assert result.returncode == 2, result.stderr
    assert expected.format(path=workdir / "broken.py") in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    sys.modules.pop("broken", None)


def test_an_id_without_its_module_says_how_to_give_it(workdir):
    result = cli_in_process("train", "--env", "user/Nav3D-v0", "--episodes", "3", cwd=workdir)
    assert result.returncode == 2
    assert "if a module of yours registers it, give MODULE:ID (as in 'mymodule:user/Nav3D-v0')" in result.stderr


def test_the_api_takes_the_module_form_and_evaluate_policy_is_sb3s(workdir):
    agent = avq.make_agent("avq", "nav3d:user/Nav3D-v0", seed=0)
    assert agent.defaults_used.env_id == "user/Nav3D-v0" and agent.defaults_used.key == "*"
    agent.learn(total_episodes=20)
    result = avq.evaluate_policy(agent, gym.make("user/Nav3D-v0"), 4, True)  # SB3's positional order
    assert result["episodes"] == 4 and len(result["returns"]) == 4
    with pytest.raises(avq.InvalidParameterError, match="n_eval_episodes must be an integer >= 1, not 0"):
        avq.evaluate_policy(agent, gym.make("user/Nav3D-v0"), n_eval_episodes=0)
    path = agent.save(workdir / "agent.zip")
    assert avq.load(path).defaults_used == agent.defaults_used


def test_a_sweep_config_takes_the_module_form(workdir):
    from avq.sweep.config import read_sweep_config

    (workdir / "sweep.yml").write_text(
        "env: nav3d:user/Nav3D-v0\nagents: [avq]\nseeds: 1\nepisodes: 2\n", encoding="utf-8"
    )
    assert read_sweep_config(workdir / "sweep.yml").env == "nav3d:user/Nav3D-v0"


@pytest.mark.parametrize(
    ("text", "name"),
    [
        ("mymodule:user/Nav3D-v0", "mymodule-user-Nav3D-v0"),
        ('a<b>c"d\\e|f?g*h', "a-b-c-d-e-f-g-h"),
        ("CON", "CON_"),
        ("nul.txt", "nul.txt_"),
        ("trailing.", "trailing"),
        ("avq-paper", "avq-paper"),
    ],
)
def test_file_name_parts_are_valid_on_every_system(text, name):
    assert file_name_part(text) == name


def test_the_default_run_directory_drops_the_module_and_the_slash():
    assert re.fullmatch(r"user-Nav3D-v0__avq__3__\d+", default_run_dir("nav3d:user/Nav3D-v0", "avq", 3).name)
    assert re.fullmatch(r"MountainCar-v0__tiles__0__\d+", default_run_dir("MountainCar-v0", "tiles", 0).name)


def test_the_defaults_of_an_id_in_the_module_form_are_the_ids():
    """The entries of the defaults are keyed by the id alone: the module of ``module:id`` does not hide them
    (``avq tune`` looks them up, and ``avq tune export`` keys its entry, with the id the study records)."""
    from avq.agents.registry import agent_class, agent_defaults, defaults_key

    assert defaults_key("avq", "somewhere:CartPole-v1") == "CartPole-v1"
    assert agent_defaults("avq", "somewhere:CartPole-v1") == agent_defaults("avq", "CartPole-v1")
    assert agent_class("avq", "somewhere:avq/GridMaze-v0") is agent_class("avq", "avq/GridMaze-v0")
    assert defaults_key("avq", "nav3d:user/Nav3D-v0") == "*"


def test_a_model_saved_as_the_how_to_saves_it_is_evaluated_and_plotted_from_the_command_line(workdir, monkeypatch):
    # The how-to's way: import the module, gym.make its id, save. The file records the module of the id's entry
    # point with the id, so that a new process imports it again.
    monkeypatch.syspath_prepend(str(workdir))  # (as a script in the working directory imports it)
    import nav3d  # noqa: F401  (registers user/Nav3D-v0 from the working directory)

    agent = avq.make_agent("avq", gym.make("user/Nav3D-v0"), seed=0).learn(total_episodes=5)
    path = agent.save(workdir / "nav3d-agent.zip")
    ev = cli_subprocess("evaluate", "nav3d-agent.zip", "--episodes", "2", "--json", cwd=workdir)
    assert ev.returncode == 0, ev.stderr
    assert json.loads(ev.stdout)["env"] == "user/Nav3D-v0"
    plot = cli_subprocess("plot", "nav3d-agent.zip", "--at", "2=0.5", "--resolution", "20", cwd=workdir)
    assert plot.returncode == 0, plot.stderr
    assert (workdir / "nav3d-agent_policy_0-1.png").is_file()
    assert avq.load(path).env.spec.id == "user/Nav3D-v0"


def test_a_model_whose_env_cannot_be_made_again_is_evaluated_with_env(workdir, tmp_path_factory):
    # A module run from its file (as runpy or importlib's spec_from_file_location do): no import finds it by name,
    # so the file records the id alone, and another process is given the environment with --env.
    elsewhere = tmp_path_factory.mktemp("elsewhere") / "byfile.py"
    elsewhere.write_text(NAV3D.replace("user/Nav3D-v0", "user/Unrecorded-v0"), encoding="utf-8")
    spec = importlib.util.spec_from_file_location("byfile_loaded", elsewhere)
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
    try:
        agent = avq.make_agent("avq", gym.make("user/Unrecorded-v0"), seed=0).learn(total_episodes=3)
        agent.save(workdir / "m.zip")
        assert avq.load(workdir / "m.zip").env.spec.id == "user/Unrecorded-v0"  # (in this process: registered)
    finally:
        gym.registry.pop("user/Unrecorded-v0", None)
    no_env = cli_subprocess("evaluate", "m.zip", "--episodes", "2", cwd=workdir)
    assert no_env.returncode == 2 and "Traceback" not in no_env.stderr
    assert "unknown environment 'user/Unrecorded-v0'" in no_env.stderr
    assert "(avq evaluate and avq plot: --env ID)" in no_env.stderr
    given = cli_subprocess(
        "evaluate", "m.zip", "--episodes", "2", "--env", "nav3d:user/Nav3D-v0", "--json", cwd=workdir
    )
    assert given.returncode == 0, given.stderr
    assert json.loads(given.stdout)["env"] == "user/Nav3D-v0"


def test_a_file_records_the_module_an_import_finds_of_its_entry_point(workdir, monkeypatch):
    monkeypatch.syspath_prepend(str(workdir))
    import nav3d

    class InMain(nav3d.Nav3D):
        pass

    InMain.__module__ = "__main__"
    cases = {
        "gymnasium.envs.classic_control.cartpole:CartPoleEnv": "user/X-v0",  # (Gymnasium's own: registered anyway)
        "avq.envs.slab_maze:SlabMaze": "user/X-v0",
        "nav3d:Nav3D": "nav3d:user/X-v0",
        nav3d.Nav3D: "nav3d:user/X-v0",
        functools.partial(nav3d.Nav3D): "nav3d:user/X-v0",  # (the partial's function's module, not functools)
        InMain: "user/X-v0",  # (a script's: another process cannot import it)
        "no_such_module_of_avq:Thing": "user/X-v0",
        "<run_path>:Thing": "user/X-v0",
    }
    for entry_point, recorded in cases.items():
        assert recorded_env_id("user/X-v0", entry_point) == recorded, entry_point
    assert recorded_env_id("other:user/X-v0", nav3d.Nav3D) == "other:user/X-v0"  # (the form given, kept)
