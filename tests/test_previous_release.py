"""Models saved by the previous release (avq 0.1.0, in tests/data/models-0.1.0/) load, and learn on exactly as
that release did: each pair of files holds one agent saved after a first budget of episodes and again after
more; this release loads the first, learns the same number of episodes, and must hold what the second holds,
array for array (wall-clock times aside). So the files stay readable and the results unchanged."""

from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

import avq
from avq.agents.plan import model as _model

DATA = Path(__file__).parent / "data" / "models-0.1.0"
#: Since 0.1.0, avq-plan merges cells under its model: its parameters (off by default), the model's count of
#: transitions that go on (m_cint), a counter in its state (S) and a column of its memory (mem_i).
ADDED_PARAMS = {"rho": None, "merge_neighbours": 3, "merge_same_action": True, "known_radius": None}
#: The noise test (ignore_noise) came later still: a file without it loads with it off (save_util.ADDED_SINCE), and
#: saves its flags (noise_dims, none) and whether the test was made (noise_tested, never).
ADDED_PARAMS["ignore_noise"] = False
#: And the cuts across one axis (off).
ADDED_PARAMS.update(collision_cut=False, axis_share=None)
#: And crossings remembered without merging (now "noise" by default; a file without it loads with it off).
ADDED_PARAMS["compose_crossings"] = False
#: Since then too, v_opt="auto" on rewards of both signs: the current episode's rewards (episode_rewards) and the
#: model's ceiling of values (a last entry of m_MP, no ceiling unless rewards of both signs were seen).
#: And the metric weighted by the values' slopes once the codebook is full (a file without it loads with it off;
#: its weights are saved once applied).
ADDED_PARAMS["reweight_when_full"] = False
#: And the floor of the growth from decisions halving as the cells settle (off; its count is a last entry of S).
ADDED_PARAMS["finer_when_settled"] = 0
ADDED_ARRAYS = {"m_cint", "episode_rewards", "noise_dims", "drift_dims", "drift_scale"}
GREW = {"S", "mem_i"}
PAIRS = sorted({re.sub(r"__\d+\.zip$", "", p.name) for p in DATA.glob("*.zip")})


def _contents(path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """Everything a saved agent holds except wall-clock times and the version that wrote it."""
    with zipfile.ZipFile(path) as zf:
        meta = json.loads(zf.read("meta.json"))
        with np.load(zf.open("arrays.npz")) as npz:
            arrays = {k: npz[k] for k in npz.files}
    meta["state"].pop("wall_s")
    meta.pop("avq_version")
    arrays["history"] = np.delete(arrays["history"], -1, axis=1)  # the wall_s column
    return meta, arrays


def test_every_agent_class_has_a_saved_pair():
    classes = {json.loads(zipfile.ZipFile(p).read("meta.json"))["class"] for p in DATA.glob("*.zip")}
    assert classes == {cls.__name__ for cls, _ in avq.AGENTS.values()}
    assert len(PAIRS) == 11


@pytest.mark.parametrize("pair", PAIRS)
def test_a_model_of_the_previous_release_loads_and_learns_on_as_it_did(tmp_path, pair):
    first, second = sorted(DATA.glob(f"{pair}__*.zip"), key=lambda p: int(p.stem.rsplit("__", 1)[1]))
    agent = avq.load(first)
    assert json.loads(zipfile.ZipFile(first).read("meta.json"))["avq_version"] == "0.1.0"
    more = int(second.stem.rsplit("__", 1)[1]) - int(first.stem.rsplit("__", 1)[1])
    agent.learn(total_episodes=more)
    meta_now, arrays_now = _contents(agent.save(tmp_path / "now.zip"))
    meta_then, arrays_then = _contents(second)
    # (a key added after 0.1.0, whose files do not say which defaults made the agent: None, read as unknown)
    assert meta_now.pop("defaults_used") is None and "defaults_used" not in meta_then
    # (the smallest reward seen, kept since v_opt="auto" is 0 on rewards of both signs: no lower than the largest)
    state_now, state_then = meta_now["state"], meta_then["state"]
    if "reward_min" in state_now and "reward_min" not in state_then:
        low, to_go = state_now.pop("reward_min"), state_now.pop("return_to_go_max")
        assert low is None or low <= state_now["reward_max"]
        assert (to_go is None) == (low is None)
    if "noise_tested" in state_now and "noise_tested" not in state_then:
        assert state_now.pop("noise_tested") is False
    # Parameters added since, at the values that keep the old behaviour (merging under a model: off).
    for name, value in ADDED_PARAMS.items():
        if name not in meta_then["params"] and name in meta_now["params"]:
            assert meta_now["params"].pop(name) == value, name
    assert meta_now == meta_then
    # Arrays added since hold nothing yet; arrays that grew a last dimension hold the old one and zeros after it.
    assert set(arrays_now) - set(arrays_then) <= ADDED_ARRAYS and set(arrays_then) <= set(arrays_now)
    for key in set(arrays_now) - set(arrays_then):
        assert not arrays_now[key].any(), key
    for key in arrays_then:
        now, then = arrays_now[key], arrays_then[key]
        if key in GREW and now.shape[:-1] == then.shape[:-1] and now.shape[-1] > then.shape[-1]:
            assert not now[..., then.shape[-1] :].any(), key
            now = now[..., : then.shape[-1]]
        if key == "m_MP" and len(now) == len(then) + 1:
            assert now[-1] == _model.NO_CEILING
            now = now[:-1]
        assert np.array_equal(now, then), key
