"""`avq reproduce` end to end on a small budget, and the CLI's answers to mistakes."""

import json
import subprocess
import sys

import pytest

from avq.cli import main

from conftest import CLI_RUNNERS


def test_reproduce_end_to_end_small_budget(tmp_path, capsys):
    out = tmp_path / "rep"
    code = main(["reproduce", "--seeds", "2", "--trials", "15", "--out", str(out), "--jobs", "1", "--no-progress"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) == {"layout", "n_states", "trials", "seeds", "warmup_s", "agents"}
    assert summary["layout"] == "lau2002" and summary["n_states"] == 98 and summary["trials"] == 15
    assert summary["seeds"] == [0, 1]
    assert list(summary["agents"]) == ["avq-paper", "avq", "tabular"]
    for res in summary["agents"].values():
        assert set(res) == {"n_cells", "success_rate", "path_ratio", "env_steps", "wall_s"}
        assert all(len(v) == 2 for v in res.values())
        assert all(isinstance(c, int) for c in res["n_cells"])
        assert all(0.0 <= s <= 1.0 for s in res["success_rate"])
        assert all(r is None or r >= 1.0 for r in res["path_ratio"])
        assert all(15 <= s <= 1500 for s in res["env_steps"])
    for name in ("partition.png", "partition-avq.png", "learning_curve.png"):
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000
    printed = capsys.readouterr().out
    assert "avq-paper" in printed and "\navq " in printed and "tabular" in printed and "success" in printed


def test_reproduce_is_reproducible(tmp_path):
    args = ["reproduce", "--seeds", "1", "--trials", "10", "--agents", "avq-paper", "--jobs", "1", "--no-progress"]
    main(args + ["--out", str(tmp_path / "a")])
    main(args + ["--out", str(tmp_path / "b")])
    a = json.loads((tmp_path / "a" / "summary.json").read_text())["agents"]["avq-paper"]
    b = json.loads((tmp_path / "b" / "summary.json").read_text())["agents"]["avq-paper"]
    assert {k: v for k, v in a.items() if k != "wall_s"} == {k: v for k, v in b.items() if k != "wall_s"}


def test_reproduce_with_a_layout_file_and_fixed_start(tmp_path):
    lay = tmp_path / "maze.txt"
    lay.write_text("#######\n#S...G#\n#.....#\n#######\n")
    out = tmp_path / "o"
    assert (
        main(
            [
                "reproduce",
                "--layout",
                str(lay),
                "--seeds",
                "1",
                "--trials",
                "5",
                "--start",
                "fixed",
                "--out",
                str(out),
                "--jobs",
                "1",
                "--no-progress",
            ]
        )
        == 0
    )
    assert json.loads((out / "summary.json").read_text())["n_states"] == 10


@pytest.mark.parametrize(
    "args,needle",
    [
        (["reproduce", "--agents", "avq-paper,bogus"], "unknown agent 'bogus'"),
        (["reproduce", "--layout", "no-such-maze"], "no-such-maze"),
        (["reproduce", "--seeds", "0"], "--seeds must be >= 1"),
        (["reproduce", "--trials", "x"], "--trials must be an integer"),
        (["reproduce", "--start", "middle"], "invalid choice"),
        (["reproduce", "--agents", ","], "at least one agent"),
        (["frobnicate"], "invalid choice"),
    ],
)
@pytest.mark.parametrize("run_cli", CLI_RUNNERS)
def test_user_mistakes_exit_2_with_one_line(args, needle, tmp_path, run_cli):
    proc = (
        run_cli(*args, "--out", str(tmp_path / "x"), cwd=tmp_path)
        if args[0] == "reproduce"
        else run_cli(*args, cwd=tmp_path)
    )
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert needle in lines[0] and "Traceback" not in proc.stderr
    assert not (tmp_path / "x" / "summary.json").exists()


def test_fixed_start_without_S_is_a_usage_error(tmp_path):
    lay = tmp_path / "m.txt"
    lay.write_text("....G\n.....\n")
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "avq.cli",
            "reproduce",
            "--layout",
            str(lay),
            "--start",
            "fixed",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and "no 'S'" in proc.stderr and "Traceback" not in proc.stderr


def test_console_script_is_installed():
    import shutil
    from pathlib import Path

    exe = shutil.which("avq") or str(Path(sys.executable).parent / "avq")
    proc = subprocess.run([exe, "--version"], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.startswith("avq ")


def test_version_is_the_installed_distributions():
    from importlib import metadata

    import avq
    from avq._version import __version__

    try:
        installed = metadata.version("avq")
    except metadata.PackageNotFoundError:
        pytest.skip("avq is not installed")
    assert avq.__version__ == __version__ == installed


def test_a_command_leaves_the_garbage_collectors_thresholds_as_they_were(capsys):
    import gc

    before = gc.get_threshold()
    assert main(["reproduce", "--agents", ","]) == 2  # (a usage error: the command ran and ended)
    assert gc.get_threshold() == before
