"""Input bounds (issue 16 item 8): implausible rig values, non-regular or oversized rig and CSV
files, deep nesting, a BOM, and write errors. Each is one line naming the file (and the field
and line where there is one), exit status 2, no traceback, nothing written."""

from __future__ import annotations

import errno
import os
import re
from pathlib import Path

import pytest
from cli_runs import one_line_error, simulate_files

from jointangle.cli.main import main
from jointangle.errors import InputError
from jointangle.recording.jrec import JrecReader, JrecWriter


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return simulate_files(tmp_path_factory, "bounds", 1)


def _with(rig_text: str, key: str, value: str, nth: int = 0) -> str:
    """The rig text with the nth `key = ...` (a value that may span lines) replaced."""
    starts = [m.start() for m in re.finditer(rf"(?m)^{re.escape(key)} = ", rig_text)]
    i = starts[nth]
    j = rig_text.index("]", i) + 1 if rig_text[i:].split("=", 1)[1].lstrip().startswith("[") \
        else rig_text.index("\n", i)
    return rig_text[:i] + f"{key} = {value}" + rig_text[j:]


def _estimate(capsys: pytest.CaptureFixture[str], rig: Path, data: Path, out: Path) -> str:
    capsys.readouterr()
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "ekf",
                 "--out", str(out)]) == 2
    assert not out.exists()  # nothing written
    return capsys.readouterr().err


@pytest.mark.parametrize(("key", "value", "nth", "needles"), [
    ("position", "[1e308, 0.0]", 0, ["links.a.sensors[0].position", "within -10 .. 10 m"]),
    ("position", "[0.1, -11]", 3, ["links.b.sensors[1].position", "-10 .. 10 m"]),
    ("joint", "[0.0, 1e9]", 1, ["links.b.joint", "-10 .. 10 m"]),
    ("rotation_deg", "1e308", 0, ["links.a.sensors[0].rotation_deg", "-360 .. 360 °"]),
    ("rotation_deg", "-400", 2, ["links.b.sensors[0].rotation_deg", "-360 .. 360 °"]),
    ("sample_rate_hz", "1e9", 0, ["sample_rate_hz", "10000 Hz"]),
    ("model", '"adxl345"\nnoise_density_ug = 1e300', 0, ["noise_density_ug", "100000"]),
    ("model", '"adxl345"\nnoise_density_ug = [290, -1, 430]', 1, ["noise_density_ug", "> 0"]),
    ("model", '"adxl345"\noffset = [0, 0, 1e12]', 2, ["links.b.sensors[0].offset", "m/s²"]),
    ("model", '"adxl345"\nS = [[2147483647, 0, 0], [0, 1, 0], [0, 0, 1]]', 0,
     ["links.a.sensors[0].S", "-10 .. 10"]),
])
def test_implausible_rig_values_are_refused(files: tuple[Path, Path], tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str], key: str,
                                            value: str, nth: int, needles: list[str]) -> None:
    data, rig = files
    bad = tmp_path / "bad.toml"
    bad.write_text(_with(rig.read_text(), key, value, nth))
    err = _estimate(capsys, bad, data, tmp_path / "est.csv")
    one_line_error(err, str(bad), "line ", "out of range", *needles)


def test_non_regular_and_oversized_rig_files(files: tuple[Path, Path], tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    fifo = tmp_path / "rig.fifo"
    os.mkfifo(fifo)
    big = tmp_path / "big.toml"
    big.write_text(rig.read_text() + "#" * (1 << 20) + "\n")
    for path, what in ((Path("/dev/urandom"), "character device"), (fifo, "FIFO"),
                       (tmp_path, "folder"), (big, "over the 1 MiB")):
        err = _estimate(capsys, path, data, tmp_path / "est.csv")  # returns at once
        one_line_error(err, str(path), what)


def test_deep_nesting_and_a_bom_are_one_line(files: tuple[Path, Path], tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    one_line_error(_estimate(capsys, deep, data, tmp_path / "e.csv"), str(deep), "nested")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + rig.read_bytes())
    one_line_error(_estimate(capsys, bom, data, tmp_path / "e.csv"), str(bom), "line 1",
                   "byte order mark (UTF-8 BOM")


def test_non_regular_and_oversized_csvs(files: tuple[Path, Path], tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str],
                                        monkeypatch: pytest.MonkeyPatch) -> None:
    data, rig = files
    fifo = tmp_path / "data.fifo"
    os.mkfifo(fifo)  # read, it would block forever
    for path, what in ((Path("/dev/urandom"), "character device"), (fifo, "FIFO")):
        err = _estimate(capsys, rig, path, tmp_path / "est.csv")
        one_line_error(err, str(path), what, "expected a CSV")
    monkeypatch.setattr("jointangle.io.csv_formats.CSV_MAX_BYTES", 1000)
    one_line_error(_estimate(capsys, rig, data, tmp_path / "est.csv"), str(data),
                   "over the 1000 bytes")


def test_write_errors_name_the_file(capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "1", "--out",
                 "/dev/full"]) == 2
    one_line_error(capsys.readouterr().err, "/dev/full", "No space left on device")
    with pytest.raises(InputError, match="/dev/full: cannot write recording: No space left"):
        JrecWriter("/dev/full", {"port": "x"}, overwrite=True)


def test_a_full_disk_mid_recording_names_the_file_and_keeps_what_was_written(
        tmp_path: Path) -> None:
    path = tmp_path / "r.jrec"
    w = JrecWriter(path, {"port": "x"})
    w.write(b"\x01\x02\x00", host_ns=1)
    real = w._f

    class Full:
        def write(self, data: bytes) -> int:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def __getattr__(self, name: str) -> object:
            return getattr(real, name)

    w._f = Full()  # type: ignore[assignment]
    with pytest.raises(InputError) as exc:
        w.write(b"\x03\x00", host_ns=2)
    assert str(path) in str(exc.value) and "No space left on device" in str(exc.value)
    w.write(b"\x04\x00", host_ns=3)  # after the error: nothing more, no second error
    w._f = real
    w.close()
    rec = JrecReader.open(path)
    assert rec.data() == b"\x01\x02\x00" and rec.damage == []
