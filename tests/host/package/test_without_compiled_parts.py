"""The pure-Python host with every compiled part hidden ($JOINTANGLE_HIDE_BUILT, as on a
machine without them, docs/packaging.md): what a user with a real board needs still works —
against the fake device on a pty, a real board's path — and each command that needs a compiled
part stops in one line naming the part and how to get it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_runs import one_line_error
from fake_device import FakeData, FakeDevice

from jointangle.built import FILTER_REPLAY, HIDE_ENV, NATIVE_BOARD, PARTS, search_build_trees
from jointangle.cli.main import main


@pytest.fixture
def hidden(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(HIDE_ENV, "1")
    for part in PARTS:
        monkeypatch.delenv(part.env, raising=False)


def test_hiding_finds_nothing(hidden: None) -> None:
    assert all(search_build_trees(p.pattern) is None for p in PARTS)


def test_pure_python_commands_work(hidden: None, tmp_path: Path, fake_data: tuple[FakeData, str],
                                   rig_file: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = tmp_path / "data.csv", tmp_path / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-slow-periodic", "--seconds", "3", "--out",
                 str(data), "--rig-out", str(rig)]) == 0
    for name in ("array-ekf", "mirror"):
        assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", name,
                     "--out", str(tmp_path / f"{name}.csv")]) == 0
    assert main(["plot", "--rig", str(rig), "--input", str(data), "--filters", "ekf",
                 "--out", str(tmp_path / "fig.png")]) == 0
    assert (tmp_path / "fig.png").stat().st_size > 1000
    assert main(["calibrate", "--rig", str(rig), "--inject-errors", "1", "--rig-out",
                 str(tmp_path / "err.toml"), "--simulate-poses", str(tmp_path / "poses.csv"),
                 "--seed", "2"]) == 0
    assert main(["calibrate", "--rig", str(tmp_path / "err.toml"), "--poses",
                 str(tmp_path / "poses.csv"), "--out", str(tmp_path / "cal.toml")]) == 0
    rec = tmp_path / "run.jrec"
    with FakeDevice(fake_data[0], tmp_path) as fake:
        capsys.readouterr()
        assert main(["info", "--port", str(fake.path), "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["protocol_version"] >= 1
        assert main(["record", "--port", str(fake.path), "--seconds", "1", "--out", str(rec),
                     "--rig", str(rig_file), "--retries", "0"]) == 0
    with FakeDevice(fake_data[0], tmp_path) as fake:  # a fresh one, as if plugged in again
        capsys.readouterr()
        assert main(["live", "--port", str(fake.path), "--json-lines", "--seconds", "1",
                     "--rig", str(rig_file), "--no-mirror"]) == 0
        rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
        assert rows and "theta_deg" in rows[-1]
    assert main(["replay", str(rec), "--verify", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["frames"] > 100 and doc["max_abs_dtheta_deg"] < 1e-3
    assert main(["doctor", "--json"]) in (0, 1)
    parts = [f for f in json.loads(capsys.readouterr().out)["findings"] if f["check"] == "parts"]
    assert [f["status"] for f in parts] == ["note"] * len(PARTS)


@pytest.mark.parametrize(("argv", "part", "what"), [
    (["estimate", "--filter", "firmware"], FILTER_REPLAY, "firmware replay library"),
    (["plot", "--filters", "ekf,firmware"], FILTER_REPLAY, "firmware replay library"),
    (["live", "--port", "sim://native", "--json-lines", "--seconds", "1"], NATIVE_BOARD,
     "sim://native needs the native virtual board"),
    (["record", "--port", "sim://native", "--seconds", "1"], NATIVE_BOARD,
     "sim://native needs the native virtual board"),
    (["info", "--port", "sim://avr"], PARTS[3], "sim://avr needs the AVR virtual board"),
    (["bench", "parity", "--json"], FILTER_REPLAY, "firmware replay library"),
])
def test_commands_needing_a_part_say_which_and_how_to_get_it(
        hidden: None, tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
        part: object, what: str) -> None:
    data, rig = tmp_path / "data.csv", tmp_path / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "1", "--out", str(data),
                 "--rig-out", str(rig)]) == 0
    files = {"estimate": ["--rig", str(rig), "--input", str(data), "--out", str(tmp_path / "e")],
             "plot": ["--rig", str(rig), "--input", str(data), "--out", str(tmp_path / "p.png")],
             "record": ["--out", str(tmp_path / "r.jrec")]}.get(argv[0], [])
    capsys.readouterr()
    assert main([*argv, *files]) == 2
    err = capsys.readouterr().err
    target, env = getattr(part, "target"), getattr(part, "env")  # noqa: B009
    one_line_error(err, what, f"--target {target}`", env, f"hidden by {HIDE_ENV}")
    assert not list(tmp_path.glob("e")) and not list(tmp_path.glob("r.jrec"))


def test_replay_verify_firmware_says_which_part(hidden: None, tmp_path: Path,
                                                fake_data: tuple[FakeData, str],
                                                rig_file: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    rec = tmp_path / "run.jrec"
    with FakeDevice(fake_data[0], tmp_path) as fake:
        assert main(["record", "--port", str(fake.path), "--seconds", "0.5", "--out", str(rec),
                     "--rig", str(rig_file), "--retries", "0"]) == 0
    capsys.readouterr()
    assert main(["replay", str(rec), "--verify-firmware"]) == 2
    one_line_error(capsys.readouterr().err, "firmware replay library", "ja_filter_replay",
                   FILTER_REPLAY.env)
