"""Input files read strictly (docs/design.md §6): a CSV cell is a number or a one-line error naming
its line and column ('#' starts no comment, whichever path of the reader finds it); a rig's
sensor list holds tables; an estimates CSV may hold NaN rates, as the tool itself writes them."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_runs import one_line_error, simulate_files

from jointangle.cli.main import main


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return simulate_files(tmp_path_factory, "csv_strict", 2)




def _write(tmp_path: Path, lines: list[str], name: str = "edited.csv") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return p


def _edited(data: Path, tmp_path: Path, lineno: int, col: str, value: str) -> Path:
    """A copy of the CSV with the cell (line number, column) replaced by `value`."""
    lines = data.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[lineno - 1].split(",")
    cells[header.index(col)] = value
    lines[lineno - 1] = ",".join(cells)
    return _write(tmp_path, lines)


def _estimate(rig: Path, csv: Path, out: Path) -> int:
    return main(["estimate", "--rig", str(rig), "--input", str(csv), "--filter", "ekf",
                 "--out", str(out)])


# --------------------------------------------------------------------- CSV cells


@pytest.mark.parametrize("cell", [
    "0.91#oops",  # in the last column, np.loadtxt's default comments='#' read this as 0.91
    "0.91 # note",  # ... and this
    "#",
    '"9.79"',  # csv.reader unquoted it in the precise check: "could not parse the table"
    "1_000",  # float() takes digit separators, np.loadtxt does not
    "\u0661",  # ARABIC-INDIC DIGIT ONE: float() takes it, np.loadtxt does not
    "",
])
@pytest.mark.parametrize("col", ["a.1.y", "omega_b"])  # omega_b: the last column
def test_a_cell_that_is_not_a_number_is_named_by_line_and_column(
        cell: str, col: str, files: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    assert data.read_text().splitlines()[0].endswith(",omega_b")
    bad = _edited(data, tmp_path, 40, col, cell)
    out = tmp_path / "e.csv"
    assert _estimate(rig, bad, out) == 2
    one_line_error(capsys.readouterr().err, f"{bad}, line 40, field '{col}': not a number")
    assert not out.exists()


@pytest.mark.parametrize("cell", [" 9.5", "9.5 ", "+9.5", "9.", ".5e1", "95E-1"])
def test_numbers_either_path_reads_are_accepted(cell: str, files: tuple[Path, Path],
                                                tmp_path: Path) -> None:
    data, rig = files
    assert _estimate(rig, _edited(data, tmp_path, 40, "a.1.y", cell), tmp_path / "e.csv") == 0


def test_a_comment_line_is_a_bad_row_and_shifts_no_line_number(
        files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    lines = data.read_text().splitlines()
    commented = _write(tmp_path, [*lines[:5], "# a note", *lines[5:]])
    assert _estimate(rig, commented, tmp_path / "e.csv") == 2
    one_line_error(capsys.readouterr().err, f"{commented}, line 6:", "found 1")


def test_a_trailing_comment_is_a_bad_cell(files: tuple[Path, Path], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    lines = data.read_text().splitlines()
    lines[9] += " # note"
    noted = _write(tmp_path, lines)
    last = lines[0].split(",")[-1]
    assert _estimate(rig, noted, tmp_path / "e.csv") == 2
    one_line_error(capsys.readouterr().err, f"line 10, field '{last}': not a number")


def test_a_utf8_bom_before_the_header_is_accepted(files: tuple[Path, Path],
                                                  tmp_path: Path) -> None:
    data, rig = files
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + data.read_bytes())
    out = tmp_path / "e.csv"
    assert _estimate(rig, bom, out) == 0
    plain = tmp_path / "plain.csv"
    assert _estimate(rig, data, plain) == 0
    assert out.read_bytes() == plain.read_bytes()


# --------------------------------------------------------------------- rig sensor lists


def _rig_with_link_a(tmp_path: Path, link_a: str) -> Path:
    body = ["sample_rate_hz = 100", "", "[links.a]", "joint = [0.3, 0.0]", link_a, "",
            "[links.b]", "joint = [0.0, 0.0]", "[[links.b.sensors]]", 'model = "adxl345"',
            "position = [0.05, 0.0]", "[[links.b.sensors]]", 'model = "adxl345"',
            "position = [0.25, 0.0]", "address = 0x1D"]
    p = tmp_path / "bad_rig.toml"
    p.write_text("\n".join(body) + "\n")
    return p


@pytest.mark.parametrize("sensors", ["sensors = [1, 2]", "sensors = [[1, 2], [3, 4]]",
                                     'sensors = ["adxl345", "adxl345"]'])
def test_a_sensor_list_of_non_tables_is_named_by_line_and_field(
        sensors: str, files: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    data, _ = files
    rig = _rig_with_link_a(tmp_path, sensors)
    assert _estimate(rig, data, tmp_path / "e.csv") == 2
    one_line_error(capsys.readouterr().err,
                    f"{rig}, line 5, field 'links.a.sensors[0]': expected a table")


def test_a_sensor_without_model_names_the_missing_field(
        files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, _ = files
    rig = _rig_with_link_a(tmp_path, "\n".join([
        "[[links.a.sensors]]", 'model = "adxl345"', "position = [0.05, 0.0]", "mux_channel = 2",
        "[[links.a.sensors]]", "position = [0.25, 0.0]", "mux_channel = 3"]))
    assert _estimate(rig, data, tmp_path / "e.csv") == 2
    one_line_error(capsys.readouterr().err, "line 9,", "field 'links.a.sensors[1].model'",
                    "missing required field")


def test_a_model_that_is_not_a_string_is_an_unknown_model(
        files: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, _ = files
    rig = _rig_with_link_a(tmp_path, "\n".join([
        "[[links.a.sensors]]", "model = [1]", "position = [0.05, 0.0]", "mux_channel = 2",
        "[[links.a.sensors]]", 'model = "adxl345"', "position = [0.25, 0.0]",
        "mux_channel = 3"]))
    assert _estimate(rig, data, tmp_path / "e.csv") == 2
    one_line_error(capsys.readouterr().err, "line 6,", "field 'links.a.sensors[0].model'",
                    "unknown sensor model [1]")


# --------------------------------------------------------------------- estimates CSVs


@pytest.mark.parametrize("name", ["analytical", "smooth"])
def test_plot_reads_the_nan_rates_estimate_writes(
        name: str, files: tuple[Path, Path], tmp_path: Path) -> None:
    data, rig = files
    est = tmp_path / f"pe_{name}.csv"
    assert main(["estimate", "--rig", str(rig), "--input", str(data), "--filter", name,
                 "--out", str(est)]) == 0
    assert "nan" in est.read_text()  # the case this is about: no rates where θ has none
    out = tmp_path / "ps.png"
    assert main(["plot", "--rig", str(rig), "--input", str(data), "--filters", "",
                 "--estimates", str(est), "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("col", ["t", "theta_deg"])
def test_nan_in_an_estimates_time_or_angle_is_still_refused(
        col: str, files: tuple[Path, Path], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    data, rig = files
    est = tmp_path / "e.csv"
    assert _estimate(rig, data, est) == 0
    capsys.readouterr()
    bad = _edited(est, tmp_path, 7, col, "nan")
    assert main(["plot", "--rig", str(rig), "--input", str(data), "--filters", "",
                 "--estimates", str(bad), "--out", str(tmp_path / "p.png")]) == 2
    one_line_error(capsys.readouterr().err, f"line 7, field '{col}'", "must be finite")
