"""Bad input on the command line (docs/design.md §6): numeric options, outputs that would overwrite
an input, implausible CSV readings and columns. Each is one line naming what is wrong and where,
exit status 2, nothing written."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from cli_runs import one_line_error, simulate_files

from jointangle.cli.main import main


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return simulate_files(tmp_path_factory, "bad_input", 2)




# --------------------------------------------------------------------- numeric options


@pytest.mark.parametrize(("argv", "field"), [
    (["plot", "--scenario", "gravity-ramp", "--seed", "-1"], "--seed"),
    (["calibrate", "--simulate-poses", "{out}", "--seed", "-1"], "--seed"),
    (["calibrate", "--simulate-poses", "{out}", "--inject-errors", "-3", "--rig-out", "{out}2"],
     "--inject-errors"),
    (["calibrate", "--poses", "{data}", "--gravity", "nan"], "--gravity"),
    (["calibrate", "--poses", "{data}", "--gravity", "inf"], "--gravity"),
    (["calibrate", "--poses", "{data}", "--gravity", "-9.8"], "--gravity"),
    (["calibrate", "--poses", "{data}", "--gravity", "0"], "--gravity"),
    (["calibrate", "--port", "sim://native", "--timeout", "-1"], "--timeout"),
    (["calibrate", "--port", "sim://native", "--hold", "nan"], "--hold"),
    (["calibrate", "--port", "sim://native", "--sim-preroll", "-1"], "--sim-preroll"),
    (["design", "--noise-ug", "0", "--rig-out", "{out}"], "--noise-ug"),
    (["design", "--noise-ug", "-1", "--rig-out", "{out}"], "--noise-ug"),
    (["design", "--la", "inf"], "--la"),
    (["design", "--margin", "-0.1"], "--margin"),
    (["design", "--seeds", "0"], "--seeds"),
    (["info", "--port", "sim://native", "--timeout", "-1"], "--timeout"),
    (["info", "--port", "sim://native", "--baud", "0"], "--baud"),
    (["info", "--port", "sim://native", "--sim-seconds", "nan"], "--sim-seconds"),
    (["record", "--port", "sim://native", "--seconds", "nan", "--out", "{out}"], "--seconds"),
    (["record", "--port", "sim://native", "--seconds", "1", "--retries", "-1", "--out",
      "{out}"], "--retries"),
    (["record", "--port", "sim://native", "--seconds", "1", "--stall", "0", "--out", "{out}"],
     "--stall"),
    (["live", "--port", "sim://native", "--seconds", "-1"], "--seconds"),
    (["simulate", "--scenario", "gravity-ramp", "--seed", "1.5", "--out", "{out}"], "--seed"),
    (["bench", "accuracy", "--jobs", "0"], "--jobs"),
    (["bench", "compare", "--seeds", "-2"], "--seeds"),
    (["bench", "host", "--seconds", "inf"], "--seconds"),
    (["bench", "protocol", "--seed", "-1"], "--seed"),
])
def test_numeric_option_out_of_its_domain_is_one_line_and_exit_2(
        argv: list[str], field: str, files: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    out = tmp_path / "out"
    argv = [a.format(out=out, data=data) for a in argv]
    if argv[0] == "calibrate":
        argv += ["--rig", str(rig)]
    assert main(argv) == 2
    one_line_error(capsys.readouterr().err, f"field '{field}'")
    assert not list(tmp_path.iterdir())  # refused before anything was written


def test_argparse_errors_are_one_line_too(files: tuple[Path, Path],
                                          capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    assert main(["estimate", "--rig", str(rig), "--input", str(data)]) == 2
    one_line_error(capsys.readouterr().err, "jointangle estimate: error:", "--filter", "--out",
                    "--help")


# --------------------------------------------------------------------- outputs over inputs


def _unchanged(path: Path, before: bytes) -> None:
    assert path.read_bytes() == before


def test_estimate_refuses_to_write_over_its_input(files: tuple[Path, Path], tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    csv = tmp_path / "data.csv"
    csv.write_bytes(data.read_bytes())
    link = tmp_path / "link.csv"
    link.symlink_to(csv)
    for out in (csv, link, tmp_path / "." / "data.csv"):
        assert main(["estimate", "--rig", str(rig), "--input", str(csv), "--filter", "ekf",
                     "--out", str(out)]) == 2
        one_line_error(capsys.readouterr().err, "field '--out'", "same file as --input")
        _unchanged(csv, data.read_bytes())
    rig_copy = tmp_path / "rig.toml"
    rig_copy.write_bytes(rig.read_bytes())
    assert main(["estimate", "--rig", str(rig_copy), "--input", str(csv), "--filter", "ekf",
                 "--out", str(rig_copy)]) == 2
    one_line_error(capsys.readouterr().err, "same file as --rig")
    _unchanged(rig_copy, rig.read_bytes())


def test_simulate_refuses_to_write_over_its_rig(files: tuple[Path, Path], tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    _, rig = files
    mine = tmp_path / "rig.toml"
    mine.write_bytes(rig.read_bytes())
    for extra in (["--out", str(mine)], ["--out", str(tmp_path / "x.csv"), "--rig-out",
                                         str(mine)]):
        assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "1", "--rig",
                     str(mine), *extra]) == 2
        one_line_error(capsys.readouterr().err, "same file as --rig")
        _unchanged(mine, rig.read_bytes())
    assert not (tmp_path / "x.csv").exists()
    both = tmp_path / "both"
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "1", "--out", str(both),
                 "--rig-out", str(both)]) == 2
    one_line_error(capsys.readouterr().err, "field '--rig-out'", "same file as --out")
    assert not both.exists()


def test_calibrate_refuses_to_write_over_its_rig(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    rig, poses = tmp_path / "rig.toml", tmp_path / "poses.csv"
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "1", "--out",
                 str(tmp_path / "d.csv"), "--rig-out", str(rig)]) == 0
    assert main(["calibrate", "--rig", str(rig), "--simulate-poses", str(poses)]) == 0
    before = rig.read_bytes()
    capsys.readouterr()
    assert main(["calibrate", "--rig", str(rig), "--poses", str(poses), "--out", str(rig)]) == 2
    one_line_error(capsys.readouterr().err, "field '--out'", "same file as --rig")
    _unchanged(rig, before)
    assert main(["calibrate", "--rig", str(rig), "--inject-errors", "1", "--rig-out", str(rig),
                 "--simulate-poses", str(tmp_path / "p2.csv")]) == 2
    one_line_error(capsys.readouterr().err, "field '--rig-out'", "same file as --rig")
    _unchanged(rig, before)
    assert not (tmp_path / "p2.csv").exists()


def test_plot_and_replay_refuse_to_write_over_an_input(
        files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    csv = tmp_path / "data.csv"
    csv.write_bytes(data.read_bytes())
    assert main(["plot", "--rig", str(rig), "--input", str(csv), "--out", str(csv)]) == 2
    one_line_error(capsys.readouterr().err, "field '--out'", "same file as --input")
    _unchanged(csv, data.read_bytes())
    rec = tmp_path / "r.jrec"
    rec.write_bytes(b"not checked: refused before it is read")
    for opt in ("--accel-csv", "--estimates-csv"):
        assert main(["replay", str(rec), opt, str(rec)]) == 2
        one_line_error(capsys.readouterr().err, f"field '{opt}'", "same file as FILE")
    assert rec.read_bytes() == b"not checked: refused before it is read"


def test_record_refuses_to_overwrite_its_rig(files: tuple[Path, Path], tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    _, rig = files
    mine = tmp_path / "rig.toml"
    mine.write_bytes(rig.read_bytes())
    assert main(["record", "--port", "sim://native?fast=1", "--seconds", "1", "--rig", str(mine),
                 "--out", str(mine), "--overwrite"]) == 2
    one_line_error(capsys.readouterr().err, "field '--out'", "same file as --rig")
    _unchanged(mine, rig.read_bytes())


# --------------------------------------------------------------------- CSV readings and columns


def _edited(data: Path, tmp_path: Path, edit: dict[tuple[int, str], str],
            extra_column: str | None = None) -> Path:
    """A copy of the CSV with cells replaced ((line number, column) -> text) and optionally a
    column of zeros appended."""
    lines = data.read_text().splitlines()
    header = lines[0].split(",")
    for (lineno, col), value in edit.items():
        cells = lines[lineno - 1].split(",")
        cells[header.index(col)] = value
        lines[lineno - 1] = ",".join(cells)
    if extra_column is not None:
        lines = [lines[0] + "," + extra_column] + [ln + ",0" for ln in lines[1:]]
    p = tmp_path / "edited.csv"
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize("value", ["1e6", "-1e300", "40"])
def test_implausible_acceleration_is_refused_naming_line_and_column(
        value: str, files: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """1e6 made the array filters raise 'Matrix is not positive definite', 1e300 turned ekf
    into NaN; 40 m/s² is beyond the rig's ±2 g ADXL345 (it saturates at 19.6 m/s²)."""
    data, rig = files
    bad = _edited(data, tmp_path, {(12, "b.1.y"): value})
    for f in ("ekf", "array-ekf"):
        assert main(["estimate", "--rig", str(rig), "--input", str(bad), "--filter", f,
                     "--out", str(tmp_path / "e.csv")]) == 2
        one_line_error(capsys.readouterr().err, str(bad), "line 12", "field 'b.1.y'",
                        "saturates")
    assert not (tmp_path / "e.csv").exists()


def test_reading_at_full_scale_is_accepted(files: tuple[Path, Path], tmp_path: Path) -> None:
    data, rig = files
    ok = _edited(data, tmp_path, {(12, "b.1.y"): "19.6133"})  # a saturated ±2 g part
    assert main(["estimate", "--rig", str(rig), "--input", str(ok), "--filter", "ekf", "--out",
                 str(tmp_path / "e.csv")]) == 0


def test_column_of_a_sensor_the_rig_lacks_is_refused(files: tuple[Path, Path], tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    for col in ("a.2.x", "b.7.gz"):
        bad = _edited(data, tmp_path, {}, extra_column=col)
        assert main(["estimate", "--rig", str(rig), "--input", str(bad), "--filter", "ekf",
                     "--out", str(tmp_path / "e.csv")]) == 2
        one_line_error(capsys.readouterr().err, "line 1", f"field '{col}'",
                        "the rig does not have")
    bad = _edited(data, tmp_path, {}, extra_column="a.0.gx")  # an ADXL345 has no gyro
    assert main(["estimate", "--rig", str(rig), "--input", str(bad), "--filter", "ekf", "--out",
                 str(tmp_path / "e.csv")]) == 2
    one_line_error(capsys.readouterr().err, "field 'a.0.gx'", "which has no gyro")
    # A gyro rig (BNO055s) with one gyro axis missing: named (it was a KeyError traceback).
    g_csv, g_rig = tmp_path / "g.csv", tmp_path / "g.toml"
    assert main(["simulate", "--scenario", "gravity-slow-periodic", "--gyros", "--seconds", "1",
                 "--out", str(g_csv), "--rig-out", str(g_rig)]) == 0
    rows = list(csv.reader(g_csv.read_text().splitlines()))
    drop = rows[0].index("a.0.gy")
    g_csv.write_text("\n".join(",".join(c for i, c in enumerate(r) if i != drop) for r in rows))
    capsys.readouterr()
    assert main(["estimate", "--rig", str(g_rig), "--input", str(g_csv), "--filter", "ekf",
                 "--out", str(tmp_path / "e.csv")]) == 2
    one_line_error(capsys.readouterr().err, "field 'a.0.gy'", "all three axes")


def test_nan_in_truth_columns_is_not_scored_but_nan_in_readings_is_refused(
        files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    est = tmp_path / "e.csv"
    partial = _edited(data, tmp_path, {(k, c): "nan" for k in range(2, 60)
                                       for c in ("theta", "omega_a", "omega_b")})
    assert main(["estimate", "--rig", str(rig), "--input", str(partial), "--filter", "ekf",
                 "--out", str(est)]) == 0
    assert main(["plot", "--rig", str(rig), "--input", str(partial), "--filters", "analytical",
                 "--estimates", str(est), "--out", str(tmp_path / "p.png")]) == 0
    capsys.readouterr()
    for col in ("t", "a.0.z"):
        bad = _edited(data, tmp_path, {(30, col): "nan"})
        assert main(["estimate", "--rig", str(rig), "--input", str(bad), "--filter", "ekf",
                     "--out", str(tmp_path / "x.csv")]) == 2
        one_line_error(capsys.readouterr().err, "line 30", f"field '{col}'", "must be finite")
