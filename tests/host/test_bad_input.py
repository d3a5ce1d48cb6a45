"""Bad input on the command line (DESIGN.md §6): numeric options. Each is one line naming what
is wrong and where, exit status 2, nothing written."""

from __future__ import annotations

from pathlib import Path

import pytest

from jointangle.cli.main import main


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    d = tmp_path_factory.mktemp("bad_input")
    data, rig = d / "data.csv", d / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-ramp", "--seconds", "2", "--out", str(data),
                 "--rig-out", str(rig)]) == 0
    return data, rig


def _one_line_error(err: str, *needles: str) -> None:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


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
    _one_line_error(capsys.readouterr().err, f"field '{field}'")
    assert not list(tmp_path.iterdir())  # refused before anything was written


def test_argparse_errors_are_one_line_too(files: tuple[Path, Path],
                                          capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    assert main(["estimate", "--rig", str(rig), "--input", str(data)]) == 2
    _one_line_error(capsys.readouterr().err, "jointangle estimate: error:", "--filter", "--out",
                    "--help")
