"""bench compare: the JSON shape, the report and its plots, and the honest-loss statements."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from jointangle.bench.compare import WHEN_TO_USE, losses, run_compare
from jointangle.cli.main import main
from jointangle.estimators.registry import ESTIMATORS


def test_every_method_has_a_when_to_use_line() -> None:
    # Ours and the neighbours have a written line; estimators added later fall back to their
    # description.
    assert set(WHEN_TO_USE) <= set(ESTIMATORS)
    assert {"array-ekf", "array-ekf-rom", "madgwick-array", "incl-kf", "ekf"} <= set(WHEN_TO_USE)


def test_compare_json_and_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rep = tmp_path / "rep"
    assert main(["bench", "compare", "--seeds", "1", "--jobs", "1", "--scenarios",
                 "gravity-impulse", "--methods", "ekf,array-ekf,madgwick-array,incl-kf",
                 "--json", "--report", str(rep)]) == 0
    doc = json.loads(capsys.readouterr().out)
    names = [m["name"] for m in doc["methods"]]
    assert names == ["ekf", "array-ekf", "madgwick-array", "incl-kf"]
    for m in doc["methods"]:
        s = m["scenarios"]["gravity-impulse"]
        assert s["theta_rms_deg"] is not None and s["theta_rms_deg"] < 5.0
        assert len(m["rms_by_speed_deg"]) == len(doc["speed_bins_dps"]) - 1
    text = (rep / "report.md").read_text()
    assert "## Where ours loses" in text and "incl-kf" in text
    assert (rep / "error_vs_speed.png").stat().st_size > 1000
    assert (rep / "error_time_gravity-impulse.png").exists()


def test_losses_name_the_neighbour_that_wins() -> None:
    doc = run_compare(["gravity-impulse"], ["array-ekf", "ekf"], n_seeds=1)
    doc["methods"][1]["scenarios"]["gravity-impulse"]["theta_rms_deg"] = 0.0  # pretend ekf wins
    out = losses(doc)
    assert any("`ekf` steady" in s for s in out)



def test_every_method_has_its_own_colour_and_marker() -> None:
    from jointangle.bench.method_styles import method_styles

    styles = method_styles([*ESTIMATORS, "later-a", "later-b"])
    assert len(ESTIMATORS) == 13
    assert len({s.colour for s in styles.values()}) == len(styles)
    assert len({s.marker for s in styles.values()}) == len(styles)
    # the same method looks the same whichever others share the plot
    assert method_styles(["incl-kf"])["incl-kf"] == styles["incl-kf"]


def test_a_method_whose_assumptions_fail_on_the_data_is_na(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """incl-kf needs gravity in the plane; the paper's slider-crank is horizontal (its output
    there was 80–171° off). Decided from the data (the sensors' z axes), not the name."""
    doc = run_compare(["paper-table2-L30"], ["array-ekf", "incl-kf"], n_seeds=1)
    ours, incl = (m["scenarios"]["paper-table2-L30"] for m in doc["methods"])
    assert ours["theta_rms_deg"] < 2.0 and ours["not_applicable"] is None
    assert incl["theta_rms_deg"] is None and incl["theta_rms_startup_deg"] is None
    assert "gravity" in incl["not_applicable"] and "plane" in incl["not_applicable"]
    assert losses(doc) == []
    from jointangle.bench.compare import write_report

    text = write_report(doc, tmp_path, "test").read_text()
    row = next(ln for ln in text.splitlines() if ln.startswith("| `incl-kf` |"))
    assert "n/a" in row and "## Not applicable (n/a)" in text
    assert "`incl-kf` on paper-table2-L30: filter 'incl-kf' needs gravity" in text
    assert main(["bench", "compare", "--seeds", "1", "--jobs", "1", "--scenarios",
                 "paper-table2-L10", "--methods", "incl-kf"]) == 0
    assert "n/a" in capsys.readouterr().out
