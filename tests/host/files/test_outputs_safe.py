"""Outputs are written whole or not at all (docs/design.md §6): a failure mid-write keeps the
file that was there, a command with several outputs checks them all before writing any, a write
error is one line naming the file; and plot's --out and options are checked before anything runs."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from cli_runs import one_line_error, simulate_files

from jointangle.bench.protocol import synthetic_log
from jointangle.cli.main import main
from jointangle.errors import InputError
from jointangle.io.atomic import atomic_path
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message, encode_message
from jointangle.protocol.framing import decode_stream
from jointangle.recording.jrec import JrecWriter

PRECIOUS = b"precious\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A 10 s accelerations CSV (1000 rows, ~200 kB) and its rig file."""
    return simulate_files(tmp_path_factory, "outputs", 10)


def _record(path: Path, data: bytes) -> Path:
    with JrecWriter(path, {"port": "sim://native"}) as w:
        for i in range(0, len(data), 97):
            w.write(data[i:i + 97], host_ns=1000 * i)
    return path


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recording with samples and estimates (sample_estimate frames)."""
    return _record(tmp_path_factory.mktemp("rec") / "r.jrec", synthetic_log(2000))




def _precious(path: Path) -> Path:
    path.write_bytes(PRECIOUS)
    return path


def _only(folder: Path, *names: str) -> None:
    """Nothing but `names` in `folder`: no temporary file left behind."""
    assert sorted(p.name for p in folder.iterdir()) == sorted(names)


# --------------------------------------------------------------------- several outputs


def test_simulate_checks_its_rig_output_before_writing_the_csv(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    keep = _precious(tmp_path / "keep.csv")
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "2", "--out", str(keep),
                 "--rig-out", str(tmp_path / "nonexist" / "r.toml")]) == 2
    one_line_error(capsys.readouterr().err, "r.toml", "field '--rig-out'", "does not exist")
    assert keep.read_bytes() == PRECIOUS
    _only(tmp_path, "keep.csv")


def test_simulate_refuses_an_output_whose_folder_is_a_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    keep = _precious(tmp_path / "keep.csv")
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "2", "--out", str(keep),
                 "--rig-out", str(keep / "r.toml")]) == 2
    one_line_error(capsys.readouterr().err, "field '--rig-out'", "not a folder")
    assert keep.read_bytes() == PRECIOUS


def test_replay_checks_every_output_before_writing_any(
        recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    acc = _precious(tmp_path / "p_acc.csv")
    assert main(["replay", str(recording), "--accel-csv", str(acc), "--estimates-csv",
                 str(tmp_path / "nonexist" / "e.csv")]) == 2
    one_line_error(capsys.readouterr().err, "e.csv", "field '--estimates-csv'", "does not exist")
    assert acc.read_bytes() == PRECIOUS
    _only(tmp_path, "p_acc.csv")


def test_replay_builds_every_csv_before_writing_any(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A recording with samples but no estimates: the estimates CSV cannot be made, so the
    accelerations CSV is not written either."""
    frames, _ = decode_stream(synthetic_log(3))
    hello = next(m for m in map(decode_message, frames) if isinstance(m, msgs.Hello))
    log = encode_message(hello, 0, 0) + b"".join(
        encode_message(msgs.Samples(sensors=tuple(msgs.SamplesSensor(0, 0, 256, 1, 0)
                                                  for _ in hello.sensors)), k, 2000 * k)
        for k in range(1, 50))
    rec = _record(tmp_path / "samples.jrec", log)
    acc = _precious(tmp_path / "p_acc.csv")
    assert main(["replay", str(rec), "--accel-csv", str(acc), "--estimates-csv",
                 str(tmp_path / "e.csv")]) == 2
    one_line_error(capsys.readouterr().err, "samples.jrec", "no estimate")
    assert acc.read_bytes() == PRECIOUS
    _only(tmp_path, "p_acc.csv", "samples.jrec")
    assert main(["replay", str(rec), "--accel-csv", str(acc)]) == 0
    assert acc.read_text().startswith("t,a.0.x")


# --------------------------------------------------------------------- a failure mid-write


def _run_with_file_size_limit(argv: list[str], limit: int) -> subprocess.CompletedProcess[str]:
    """The CLI in a process that cannot write past `limit` bytes of any file: every write
    beyond fails with EFBIG (Python ignores SIGXFSZ), as a full disk would."""
    def limit_size() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    return subprocess.run([sys.executable, "-m", "jointangle", *argv], capture_output=True,
                          text=True, timeout=240, preexec_fn=limit_size, env=env, check=False)


Argv = Callable[[Path, Path, Path, Path], list[str]]

MID_WRITE: dict[str, Argv] = {
    "simulate --out": lambda out, data, rig, rec: [
        "simulate", "--scenario", "gravity-ramp", "--seconds", "10", "--out", str(out)],
    "simulate --rig-out": lambda out, data, rig, rec: [
        "simulate", "--scenario", "gravity-ramp", "--seconds", "0.02", "--out",
        str(out.with_name("small.csv")), "--rig-out", str(out)],
    "estimate --out": lambda out, data, rig, rec: [
        "estimate", "--rig", str(rig), "--input", str(data), "--filter", "analytical",
        "--out", str(out)],
    "replay --accel-csv": lambda out, data, rig, rec: [
        "replay", str(rec), "--accel-csv", str(out)],
    "replay --estimates-csv": lambda out, data, rig, rec: [
        "replay", str(rec), "--estimates-csv", str(out)],
    "plot --out": lambda out, data, rig, rec: [
        "plot", "--rig", str(rig), "--input", str(data), "--filters", "analytical",
        "--out", str(out)],
}


@pytest.mark.parametrize("case", MID_WRITE)
def test_a_failure_mid_write_keeps_the_file_that_was_there(
        case: str, files: tuple[Path, Path], recording: Path, tmp_path: Path) -> None:
    data, rig = files
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    name = {"simulate --rig-out": "r.toml", "plot --out": "p.png"}.get(case, "keep.csv")
    keep = _precious(out_dir / name)
    # The 2-row CSV of "simulate --rig-out" (~340 B) fits, its rig (~680 B) does not; every
    # other output is well over 8 kB.
    limit = 512 if case == "simulate --rig-out" else 8192
    proc = _run_with_file_size_limit(MID_WRITE[case](keep, data, rig, recording), limit)
    assert proc.returncode == 2, proc.stderr
    one_line_error(proc.stderr, str(keep), "cannot write")
    assert keep.read_bytes() == PRECIOUS
    left = {"simulate --rig-out": ("r.toml", "small.csv")}.get(case, (name,))
    _only(out_dir, *left)


# --------------------------------------------------------------------- write errors name the file


def test_a_write_error_names_the_file(files: tuple[Path, Path],
                                      capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "analytical",
                 "--out", "/dev/full"]) == 2
    one_line_error(capsys.readouterr().err, "jointangle estimate: error: /dev/full:",
                    "No space left on device")


def test_special_files_are_written_in_place(files: tuple[Path, Path]) -> None:
    """/dev/null stays a device (no temporary file beside it, no replacing it), and
    /dev/stdout works on a pipe (it resolves to no path there)."""
    data, rig = files
    argv = ["estimate", "--rig", str(rig), "--input", str(data), "--filter", "analytical"]
    assert main([*argv, "--out", "/dev/null"]) == 0
    assert Path("/dev/null").is_char_device()
    proc = subprocess.run([sys.executable, "-m", "jointangle", *argv, "--out", "/dev/stdout"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("t,theta_deg,omega_a_dps,omega_b_dps")
    assert len(proc.stdout.splitlines()) == 1001


def test_atomic_path_replaces_only_when_complete(tmp_path: Path) -> None:
    out = _precious(tmp_path / "o.csv")
    out.chmod(0o640)
    with pytest.raises(RuntimeError), atomic_path(out) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed mid-write")
    assert out.read_bytes() == PRECIOUS
    _only(tmp_path, "o.csv")
    with atomic_path(out) as tmp:
        tmp.write_text("whole\n")
        assert out.read_bytes() == PRECIOUS  # not yet
    assert out.read_text() == "whole\n"
    assert out.stat().st_mode & 0o777 == 0o640  # the file's permissions are kept
    _only(tmp_path, "o.csv")


def test_atomic_path_writes_through_a_symlink(tmp_path: Path) -> None:
    real = _precious(tmp_path / "real.csv")
    link = tmp_path / "link.csv"
    link.symlink_to(real)
    with atomic_path(link) as tmp:
        tmp.write_text("new\n")
    assert link.is_symlink() and real.read_text() == "new\n"


def test_atomic_path_refuses_a_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="is a folder"), atomic_path(tmp_path):
        pass


# --------------------------------------------------------------------- plot --out and options


@pytest.fixture
def no_estimator(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if plot runs an estimator (it must refuse its command line first)."""
    def refuse(*_: object) -> None:
        raise AssertionError("an estimator ran before the command line was checked")

    monkeypatch.setattr("jointangle.cli.plot.run_estimator", refuse)
    monkeypatch.setattr("jointangle.cli.plot.simulate", refuse)


@pytest.mark.parametrize(("out", "needle"), [
    ("i.xyz", "unknown image format .xyz"),
    ("i_noext", "no file extension"),
    ("/dev/full", "no file extension"),
])
def test_plot_refuses_an_out_it_cannot_write_before_running_anything(
        out: str, needle: str, no_estimator: None, tmp_path: Path,
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["plot", "--scenario", "gravity-ramp", "--out", out]) == 2
    one_line_error(capsys.readouterr().err, f"{out}, field '--out'", needle, ".png", ".svg")
    _only(tmp_path)


def test_plot_refuses_an_out_in_a_missing_folder_before_running_anything(
        no_estimator: None, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "nonexist" / "p.png"
    assert main(["plot", "--scenario", "gravity-ramp", "--out", str(out)]) == 2
    one_line_error(capsys.readouterr().err, str(out), "field '--out'", "does not exist")


def test_plot_refuses_rig_with_scenario(no_estimator: None, files: tuple[Path, Path],
                                        tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    _, rig = files
    out = tmp_path / "x.png"
    assert main(["plot", "--scenario", "gravity-impulse", "--rig", str(rig), "--out",
                 str(out)]) == 2
    one_line_error(capsys.readouterr().err, "field '--rig'", "--scenario")
    assert not out.exists()


@pytest.mark.parametrize("out", ["p.svg", "p.PDF"])
def test_plot_writes_exactly_the_path_it_reports(
        out: str, files: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    path = tmp_path / out
    assert main(["plot", "--rig", str(rig), "--input", str(data), "--filters", "analytical",
                 "--out", str(path)]) == 0
    assert f"wrote {path}" in capsys.readouterr().err
    _only(tmp_path, out)
    head = path.read_bytes()[:5]
    assert head == (b"%PDF-" if out.endswith("PDF") else b"<?xml")
