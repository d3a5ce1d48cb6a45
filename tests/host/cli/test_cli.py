"""The command line as a user types it: simulate, estimate, bench, plot, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from jointangle.cli.main import main
from jointangle.io.csv_formats import read_estimates_csv


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    d = tmp_path_factory.mktemp("cli")
    data, rig = d / "data.csv", d / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-ramp", "--seed", "1", "--seconds", "3",
                 "--rate", "200", "--out", str(data), "--rig-out", str(rig)]) == 0
    return data, rig


def test_simulate_writes_the_csv_contract(files: tuple[Path, Path]) -> None:
    data, _ = files
    lines = data.read_text().splitlines()
    assert lines[0] == ("t,a.0.x,a.0.y,a.0.z,a.1.x,a.1.y,a.1.z,b.0.x,b.0.y,b.0.z,b.1.x,b.1.y,"
                        "b.1.z,theta,omega_a,omega_b")
    assert len(lines) == 1 + 600  # 3 s at 200 Hz


def test_estimate_output_and_wrapping(files: tuple[Path, Path], tmp_path: Path) -> None:
    data, rig = files
    out = tmp_path / "est.csv"
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "array-ekf",
                 "--out", str(out)]) == 0
    header = out.read_text().splitlines()[0]
    assert header.startswith("t,theta_deg,omega_a_dps,omega_b_dps")
    est = read_estimates_csv(out)
    assert np.all(est.theta_deg > -180.0) and np.all(est.theta_deg <= 180.0)
    truth = np.loadtxt(data, delimiter=",", skiprows=1)[:, -3]
    err = np.degrees(np.angle(np.exp(1j * (np.radians(est.theta_deg) - truth))))
    assert np.sqrt(np.mean(err[200:] ** 2)) < 1.0


def test_bench_accuracy_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "accuracy", "--json", "--seeds", "2", "--jobs", "1",
                 "--scenarios", "paper-table2-L30", "--filters", "smooth,ukf,array-rts"]) == 0
    doc = json.loads(capsys.readouterr().out)
    sc = doc["scenarios"][0]
    assert sc["name"] == "paper-table2-L30"
    assert set(sc["filters"]) == {"smooth", "ukf", "array-rts"}
    keys = {"theta_rms_deg", "theta_rms_startup_deg", "theta_worst_seed_deg",
            "omega_a_rms_dps", "omega_b_rms_dps", "latency_ms"}
    for f in sc["filters"].values():
        assert keys <= set(f)
    assert sc["filters"]["ukf"]["latency_ms"] == 0
    assert sc["filters"]["smooth"]["latency_ms"] == 120
    assert sc["filters"]["array-rts"]["latency_ms"] is None
    assert sc["filters"]["smooth"]["omega_a_rms_dps"] is None
    assert sc["paper"]["theta_rms_deg"]["ekf"] == 0.71
    assert 0.2 < sc["filters"]["ukf"]["theta_rms_deg"] < 3.0


def test_plot_writes_png(files: tuple[Path, Path], tmp_path: Path) -> None:
    data, rig = files
    est = tmp_path / "est.csv"
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "ekf",
                 "--out", str(est)]) == 0
    png = tmp_path / "fig.png"
    assert main(["plot", "--rig", str(rig), "--input", str(data), "--filters", "analytical",
                 "--estimates", str(est), "--out", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _estimate(rig: Path, data: Path, tmp_path: Path) -> int:
    return main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "ekf",
                 "--out", str(tmp_path / "e.csv")])


def _edit_cell(data: Path, tmp_path: Path, row: int, col: int, value: str) -> Path:
    lines = data.read_text().splitlines()
    cells = lines[row].split(",")
    cells[col] = value
    lines[row] = ",".join(cells)
    p = tmp_path / "edited.csv"
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize(("value", "reason"), [("abc", "not a number"), ("nan", "must be finite")])
def test_bad_cell_names_file_line_and_field(files: tuple[Path, Path], tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str], value: str,
                                            reason: str) -> None:
    data, rig = files
    bad = _edit_cell(data, tmp_path, 42, 5, value)
    assert _estimate(rig, bad, tmp_path) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "line 43" in err and "field 'a.1.y'" in err and reason in err


def test_missing_column_is_named(files: tuple[Path, Path], tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    lines = data.read_text().splitlines()
    drop = lines[0].split(",").index("b.0.y")
    bad = tmp_path / "missing.csv"
    bad.write_text("\n".join(",".join(c for i, c in enumerate(ln.split(",")) if i != drop)
                             for ln in lines) + "\n")
    assert _estimate(rig, bad, tmp_path) == 2
    err = capsys.readouterr().err
    assert "line 1" in err and "field 'b.0.y'" in err


def test_wrong_sensor_count_is_named(files: tuple[Path, Path], tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    text = rig.read_text()
    # A rig with a third sensor on link b expects b.2.* columns the CSV does not have.
    extra = text.rstrip() + (
        '\n\n[[links.b.sensors]]\nmodel = "adxl345"\nposition = [0.15, 0.0]\n'
        "mux_channel = 5\naddress = 0x53\nrange_g = 2\n")
    rig3 = tmp_path / "rig3.toml"
    rig3.write_text(extra)
    assert _estimate(rig3, data, tmp_path) == 2
    err = capsys.readouterr().err
    assert "b.2.x" in err and "the rig has 5 sensors" in err and "the CSV has 4" in err


def test_malformed_rig_is_named(files: tuple[Path, Path], tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    bad = tmp_path / "bad.toml"
    bad.write_text(rig.read_text().replace('range_g = 2', 'range_g = "two"', 1))
    assert _estimate(bad, data, tmp_path) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "field 'links.a.sensors[0].range_g'" in err and "line" in err


def test_unknown_filter_exits_2(files: tuple[Path, Path], tmp_path: Path,
                                capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "kalman",
                 "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "field '--filter'" in err and "invalid choice" in err


def test_every_subcommand_has_help(capsys: pytest.CaptureFixture[str]) -> None:
    for cmd in ("simulate", "estimate", "bench", "plot"):
        with pytest.raises(SystemExit) as exc:
            main([cmd, "--help"])
        assert exc.value.code == 0
        assert "usage: jointangle" in capsys.readouterr().out


def test_simulate_with_gyros_feeds_the_gyro_method(tmp_path: Path) -> None:
    data, rig, est = tmp_path / "g.csv", tmp_path / "g.toml", tmp_path / "e.csv"
    assert main(["simulate", "--scenario", "gravity-slow-periodic", "--gyros", "--seconds", "4",
                 "--out", str(data), "--rig-out", str(rig)]) == 0
    header = data.read_text().splitlines()[0].split(",")
    assert "a.0.gz" in header and "b.1.gz" in header
    assert 'model = "bno055"' in rig.read_text()
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "incl-kf",
                 "--out", str(est)]) == 0
    assert len(read_estimates_csv(est).t) == 400


def test_json_summaries(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, rig, est = tmp_path / "d.csv", tmp_path / "r.toml", tmp_path / "e.csv"
    assert main(["simulate", "--scenario", "paper-table2-L30", "--seconds", "1", "--out",
                 str(data), "--rig-out", str(rig), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["samples"] == 100 and doc["sensors"] == 4
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "smooth",
                 "--out", str(est), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc == {"filter": "smooth", "out": str(est), "samples": 100, "latency_ms": 120.0,
                   "unobservable_fraction": 0.0}


def test_unwritable_output_is_one_line_and_exit_2(files: tuple[Path, Path], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    out = tmp_path / "no such folder" / "est.csv"
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", "ekf",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "est.csv" in err and "Traceback" not in err


def test_rig_that_is_not_utf8_is_named(files: tuple[Path, Path], tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(rig.read_bytes().replace(b'name = "', b'name = "\xe9', 1))
    assert _estimate(bad, data, tmp_path) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "UTF-8" in err


def test_coincident_sensors_name_the_rig_file(files: tuple[Path, Path], tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    import re

    data, rig = files
    text = rig.read_text()
    first, second = re.findall(r"position = \[[^\]]*\]", text)[:2]
    bad = tmp_path / "coincident.toml"
    bad.write_text(text.replace(second, first, 1))
    assert _estimate(bad, data, tmp_path) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "coincident" in err
    # live and record refuse it before the board would stream an unconfigured filter's zeros
    assert main(["live", "--port", "sim://native?fast=1", "--rig", str(bad),
                 "--seconds", "1", "--json"]) == 2
    assert main(["record", "--port", "sim://native?fast=1", "--rig", str(bad),
                 "--seconds", "1", "--out", str(tmp_path / "x.jrec")]) == 2
    assert not (tmp_path / "x.jrec").exists()
    assert capsys.readouterr().err.count("(nearly) coincident") == 2


@pytest.mark.parametrize(("bad", "field"), [
    (["--seconds", "nan"], "--seconds"), (["--seconds", "inf"], "--seconds"),
    (["--seed", "-1"], "--seed"), (["--rate", "0.5", "--seconds", "1"], "--seconds"),
    (["--seconds", "1e7"], "--seconds"), (["--rate", "nan"], "--rate")])
def test_simulate_refuses_runs_it_cannot_make(bad: list[str], field: str, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "x.csv"
    assert main(["simulate", "--scenario", "gravity-ramp", *bad, "--out", str(out)]) == 2
    assert f"field '{field}'" in capsys.readouterr().err
    assert not out.exists()
