"""reports/accuracy.md is what `jointangle bench accuracy --markdown` gives for the tree as it is.

The report records the command that wrote it and a fingerprint of the code its figures depend on
(estimators, the firmware core, the simulator and scenarios, the scoring; bench/report.py). This
recomputes the fingerprint — cheap — instead of re-running the benchmark (minutes).
"""

from __future__ import annotations

from pathlib import Path

from jointangle.bench.report import REPO, fingerprint, report_header, source_hashes, stale_sources

REPORT = REPO / "reports" / "accuracy.md"


def test_the_accuracy_report_matches_the_code_that_produces_its_figures() -> None:
    text = REPORT.read_text(encoding="utf-8")
    stale = stale_sources(text)
    assert stale is None, (
        f"reports/accuracy.md is stale: {', '.join(stale[1])} changed since it was generated; "
        f"regenerate it: {stale[0]} --jobs 2 > reports/accuracy.md")


def test_a_changed_estimator_makes_the_report_stale(tmp_path: Path) -> None:
    tree = tmp_path / "repo"
    (tree / "host/jointangle/estimators").mkdir(parents=True)
    (tree / "firmware/core").mkdir(parents=True)
    est = tree / "host/jointangle/estimators/ekf.py"
    core = tree / "firmware/core/joint_filter.hpp"
    est.write_text('"""Doc."""\nGAIN = 1.0  # a comment\n')
    core.write_text("// comment\nint Gain() { return 1; }\n")
    command = "jointangle bench accuracy --markdown --seeds 2"
    report = report_header(command, tree) + "\n\n| table |\n"
    report += "\n".join(f"<!-- file {d} {p} -->" for p, d in source_hashes(tree).items())
    assert stale_sources(report, tree) is None
    # Comments, docstrings and layout do not change a figure ...
    est.write_text('"""Another doc."""\nGAIN = 1.0  # another comment\n')
    core.write_text("/* block */ int Gain()  {\n  return 1;\n}\n")
    assert stale_sources(report, tree) is None
    # ... code does, and the test names the file.
    est.write_text("GAIN = 2.0\n")
    assert stale_sources(report, tree) == (command, ["host/jointangle/estimators/ekf.py"])
    assert fingerprint(command, source_hashes(tree)) not in report


def test_the_report_was_written_with_the_default_seeds() -> None:
    assert "<!-- generated: jointangle bench accuracy --markdown --seeds 20 -->" in \
        REPORT.read_text(encoding="utf-8")
