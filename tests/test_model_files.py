"""Saved agents: exact round trips, and a clear error naming the file for every damaged or foreign one."""

from __future__ import annotations

import io
import json
import zipfile

import gymnasium as gym
import numpy as np
import pytest

import avq

NAMES = ["avq-paper", "avq", "tabular", "grid", "tiles"]


def _env(name):
    return gym.make("MountainCar-v0") if name in ("grid", "tiles", "avq") else gym.make("avq/GridMaze-v0")


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """One trained, saved agent of every kind: name -> (path, agent)."""
    out = {}
    for name in NAMES:
        agent = avq.make_agent(name, _env(name), seed=2).learn(total_episodes=3)
        out[name] = (agent.save(tmp_path_factory.mktemp(name) / "m.zip"), agent)
    return out


def _rewrite(src, dst, meta=None, arrays=None):
    """A copy of a saved model with its header and/or arrays changed."""
    with zipfile.ZipFile(src) as zf:
        m = json.loads(zf.read("meta.json"))
        with np.load(io.BytesIO(zf.read("arrays.npz"))) as npz:
            a = {k: npz[k] for k in npz.files}
    if meta:
        meta(m)
    if arrays:
        arrays(a)
    buf = io.BytesIO()
    np.savez(buf, **a)
    with zipfile.ZipFile(dst, "w") as zf:
        zf.writestr("meta.json", json.dumps(m))
        zf.writestr("arrays.npz", buf.getvalue())
    return dst


@pytest.mark.parametrize("name", NAMES)
def test_round_trip_is_bit_for_bit(saved, name):
    path, agent = saved[name]
    loaded = avq.load(path, env=_env(name))
    assert loaded.get_params() == agent.get_params()
    assert (loaded.num_timesteps, loaded.num_episodes) == (agent.num_timesteps, agent.num_episodes)
    mine, theirs = agent._state_dict()[1], loaded._state_dict()[1]  # every learned array
    assert mine.keys() == theirs.keys() and all(np.array_equal(mine[k], theirs[k]) for k in mine)
    obs = np.stack([_env(name).observation_space.sample() for _ in range(50)]).astype(np.float64)
    assert np.array_equal(loaded.predict(obs)[0], agent.predict(obs)[0])


def _learned(agent):
    return {**agent._state_dict()[1], "steps": agent.num_timesteps, "params": str(agent.get_params())}


def _same(a, b):
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("name", NAMES)
def test_truncated_and_corrupted_files_name_the_file(saved, name, tmp_path):
    path, _ = saved[name]
    data = path.read_bytes()
    for cut in (0, 10, len(data) // 2, len(data) - 1):
        bad = tmp_path / f"cut{cut}.zip"
        bad.write_bytes(data[:cut])
        with pytest.raises(ValueError, match=f"cut{cut}.zip"):
            avq.load(bad, env=_env(name))
    for bit, what in ((0x01, "encrypted"), (0x20, "patched")):  # general-purpose flags zipfile cannot read
        flagged = bytearray(data)
        for start in range(len(data) - 4):  # the flags of every central directory entry (what zipfile reads)
            if data[start : start + 4] == b"PK\x01\x02":
                flagged[start + 8] |= bit
        bad = tmp_path / f"{what}.zip"
        bad.write_bytes(bytes(flagged))
        with pytest.raises(ValueError, match=f"{what}.zip"):
            avq.load(bad, env=_env(name))
    rng = np.random.default_rng(0)
    original = _learned(avq.load(path, env=_env(name)))
    detected = 0
    for k in range(20):
        # A flipped byte anywhere either fails with the file's name (the zip's checksums catch what the
        # parsers would not) or hit a byte nothing depends on (a header's timestamp, say): then the
        # loaded agent is the saved one, never a silently different one.
        corrupt = bytearray(data)
        at = int(rng.integers(len(data)))
        corrupt[at] ^= 0xFF
        bad = tmp_path / f"flip{k}.zip"
        bad.write_bytes(bytes(corrupt))
        try:
            loaded = avq.load(bad, env=_env(name))
        except (ValueError, FileNotFoundError) as e:
            assert f"flip{k}.zip" in str(e)
            detected += 1
        else:
            assert _same(_learned(loaded), original), f"byte {at} changed the loaded agent silently"
    assert detected >= 15


def test_foreign_and_incompatible_files(saved, tmp_path):
    path, _ = saved["avq-paper"]
    env = gym.make("avq/GridMaze-v0")
    foreign = tmp_path / "foreign.zip"
    with zipfile.ZipFile(foreign, "w") as zf:
        zf.writestr("data.csv", "a,b\n")
    cases = {
        foreign: "not a readable avq model",
        _rewrite(path, tmp_path / "header.zip", meta=lambda m: m.update(format="other")): "no avq-agent header",
        _rewrite(path, tmp_path / "version.zip", meta=lambda m: m.update(format_version=99)): "version 99",
        _rewrite(path, tmp_path / "cls.zip", meta=lambda m: m.update({"class": "Nope"})): "unknown agent class",
        _rewrite(path, tmp_path / "param.zip", meta=lambda m: m["params"].update(alpha=7)): "alpha",
        _rewrite(path, tmp_path / "extra.zip", meta=lambda m: m["params"].update(colour=1)): "not valid",
        _rewrite(path, tmp_path / "rng.zip", meta=lambda m: m["state"].update(rng="x")): "inconsistent",
        _rewrite(path, tmp_path / "shape.zip", arrays=lambda a: a.update(q=a["q"][:, :2])): "shapes",
        _rewrite(path, tmp_path / "nan.zip", arrays=lambda a: a["q"].__setitem__((0, 0), np.nan)): "NaN",
        _rewrite(path, tmp_path / "str.zip", arrays=lambda a: a.update(q=np.array(["a"]))): "dtype",
        _rewrite(path, tmp_path / "gone.zip", arrays=lambda a: a.pop("codebook")): "incomplete",
        _rewrite(path, tmp_path / "hist.zip", arrays=lambda a: a.update(history=a["history"][:1])): "history",
    }
    for bad, needle in cases.items():
        with pytest.raises(ValueError, match=needle) as info:
            avq.load(bad, env=env)
        assert bad.name in str(info.value)


def test_pickled_arrays_are_never_unpickled(saved, tmp_path):
    path, _ = saved["tabular"]
    with zipfile.ZipFile(path) as zf:
        meta = zf.read("meta.json")
    buf = io.BytesIO()
    np.savez(buf, q=np.array([object()], dtype=object))  # np.savez pickles object arrays
    bad = tmp_path / "pickle.zip"
    with zipfile.ZipFile(bad, "w") as zf:
        zf.writestr("meta.json", meta)
        zf.writestr("arrays.npz", buf.getvalue())
    with pytest.raises(ValueError, match="pickle.zip.*unreadable"):
        avq.load(bad, env=gym.make("avq/GridMaze-v0"))


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothing.zip"):
        avq.load(tmp_path / "nothing.zip")


def test_loading_without_env_remakes_the_environment_with_its_make_arguments(tmp_path):
    from avq.envs import random_layout

    rows = random_layout(14, 12, 0.25, seed=3)
    env = gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=150)
    agent = avq.make_agent("tabular", env, seed=0).learn(total_episodes=20)
    loaded = avq.load(agent.save(tmp_path / "m.zip"))
    assert loaded.env.unwrapped.layout.rows == tuple(rows) and loaded.env.spec.max_episode_steps == 150
    straight = avq.make_agent("tabular", gym.make("avq/GridMaze-v0", layout=rows, max_episode_steps=150), seed=0)
    straight.learn(total_episodes=30)
    loaded.learn(total_episodes=10)
    assert np.array_equal(straight.q_, loaded.q_)


def test_version_1_files_without_history_still_load_but_version_2_needs_it(saved, tmp_path):
    path, agent = saved["tabular"]

    def old(m):
        m.update(format_version=1)
        m.pop("env_make")

    v1 = _rewrite(path, tmp_path / "v1.zip", meta=old, arrays=lambda a: a.pop("history"))
    loaded = avq.load(v1, env=gym.make("avq/GridMaze-v0"))
    assert np.array_equal(loaded.q_, agent.q_) and len(loaded.history_) == 0
    v2 = _rewrite(path, tmp_path / "v2.zip", arrays=lambda a: a.pop("history"))
    with pytest.raises(ValueError, match="v2.zip.*no history"):
        avq.load(v2, env=gym.make("avq/GridMaze-v0"))
