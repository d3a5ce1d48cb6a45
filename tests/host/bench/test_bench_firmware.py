"""`jointangle bench firmware`: artefact lookup, the step-cycle run, the loop run on the real
image in the AVR virtual board, the sustained-rate verdict and the table."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from jointangle.bench import firmware as fw
from jointangle.cli import bench_firmware
from jointangle.cli.main import main
from jointangle.errors import InputError


def test_a_tree_without_the_image_names_its_target(tmp_path: Path) -> None:
    tree = tmp_path / "b"
    (tree / "firmware" / "sim").mkdir(parents=True)
    (tree / "avr").mkdir()
    (tree / "CMakeCache.txt").write_text("")
    for p in (tree / "firmware" / "avr_cycles", tree / "avr" / "bench_filter.elf",
              tree / "firmware" / "sim" / "ja_avr_board"):
        p.write_text("")
    with pytest.raises(InputError, match=r"jointangle_mega2560\.elf is not built.*avr_images"):
        fw.locate(tree, build=False)
    assert fw.locate(tree, build=False, need_image=False).tree == tree
    with pytest.raises(InputError, match="CMakeCache"):
        fw.locate(tmp_path / "nowhere", build=False)


def _run(rate: int, loop_rate: float, **kw: int) -> fw.LoopRun:
    args: dict[str, int] = {"frames": 100, "frames_lost": 0, "stale_frames": 0, "overruns": 0,
                            "uart_drops": 0}
    args.update(kw)
    rep = {"loop_rate_hz": loop_rate, "idle_fraction": 0.3, "bus": {"occupancy": 0.4}}
    return fw.LoopRun(rate, "adxl345", rep, **args)


def test_a_promised_rate_needs_its_share_of_cycles_asleep() -> None:
    run = _run(300, 300.0)  # 30 % asleep
    assert run.sustained() == (True, "")
    assert run.sustained(min_asleep=0.2) == (True, "")
    ok, why = run.sustained(min_asleep=0.4)
    assert not ok and "30.0 % asleep" in why


def test_sustained_needs_the_rate_fresh_samples_and_no_overrun_or_loss() -> None:
    assert _run(500, 499.9).sustained() == (True, "")
    assert "loop rate 400 Hz" in _run(500, 400).sustained()[1]
    assert "3 overruns" in _run(500, 500, overruns=3).sustained()[1]
    assert "stale" in _run(500, 500, stale_frames=1).sustained()[1]
    assert "frames lost" in _run(500, 500, frames_lost=2).sustained()[1]
    assert "no frames" in _run(500, 500, frames=0).sustained()[1]


def test_loop_split_is_per_filter_step() -> None:
    rep = {"loops": 10, "sleep_cycles": 1000,
           "activity": {"3": {"cycles": 400000}, "1": {"cycles": 5000}, "9": {"cycles": 10}}}
    assert fw.loop_split(rep) == {"twi_isr": 500.0, "filter": 40000.0, "id9": 1.0,
                                  "sleep": 100.0}


def test_sweep_goes_up_while_sustained_and_down_when_not(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    limit = {"up": 700, "down": 200}
    which = "up"

    def fake_run(art: Any, model: str, rate: int, window_s: float, work: Path,
                 per_link: int = 2, stream: str = "full",
                 channel_per_link: bool = False) -> fw.LoopRun:
        return _run(rate, rate if rate <= limit[which] else 0.5 * rate)

    monkeypatch.setattr(fw, "run_loop", fake_run)
    out = fw.max_sustained_rate(None, "adxl345", 1.0, tmp_path, lambda _: None)  # type: ignore[arg-type]
    assert out["max_rate_hz"] == 700
    assert [t["rate_hz"] for t in out["tried"]] == [500, 600, 700, 705, 710, 725, 750, 800]
    which = "down"
    out = fw.max_sustained_rate(None, "bno055", 1.0, tmp_path, lambda _: None)  # type: ignore[arg-type]
    assert out["max_rate_hz"] == 200
    assert [t["rate_hz"] for t in out["tried"]] == [200, 205, 210, 225, 250, 300, 400, 500]
    limit["down"] = 345  # bisected to 5 Hz between 300 and 400
    out = fw.max_sustained_rate(None, "adxl345", 1.0, tmp_path, lambda _: None)  # type: ignore[arg-type]
    assert out["max_rate_hz"] == 345
    assert [t["rate_hz"] for t in out["tried"]] == [300, 325, 335, 340, 345, 350, 400, 500]


def _artefacts() -> fw.Artefacts:
    """The real artefacts (the integrator's build tree, or $JOINTANGLE_BUILD_DIR)."""
    return fw.locate(fw.env_build_dir(), build=False)


def test_step_cycles_times_every_step_of_both_builds(tmp_path: Path) -> None:
    steps = fw.step_cycles(_artefacts(), tmp_path, ["gravity-ramp"], seconds=0.5)  # 100 Hz
    assert steps["steps"] == 50
    assert steps["fixed"]["count"] >= 50 and steps["float"]["count"] >= 50
    assert 1000 < steps["fixed"]["worst"] < steps["float"]["worst"]


def test_step_sections_add_up_to_the_step(tmp_path: Path) -> None:
    """`bench firmware --sections`: every section of every step of both builds is timed, and
    the sections' means add up to the step's mean (the same steps through the plain bench)."""
    art = _artefacts()
    sec = fw.step_sections(art, tmp_path, ["gravity-ramp"], seconds=0.5)
    steps = fw.step_cycles(art, tmp_path, ["gravity-ramp"], seconds=0.5)
    assert list(sec) == list(fw.STEP_SECTIONS)
    for build in ("fixed", "float"):
        assert all(v[build]["count"] == 50 and v[build]["worst"] > 0 for v in sec.values())
        total = sum(v[build]["mean"] for v in sec.values())
        assert total == pytest.approx(steps[build]["mean"], rel=0.01), (build, total, steps)
    # The sequential updates are the largest part of the fixed step (FILTER.md).
    assert max(sec, key=lambda k: sec[k]["fixed"]["mean"]) == "updates"


def test_loop_run_on_the_real_image_accounts_for_every_cycle(tmp_path: Path) -> None:
    run = fw.run_loop(_artefacts(), "adxl345", 500, 0.5, tmp_path)
    rep = run.report
    assert rep["seconds"] == pytest.approx(0.5, abs=0.01)
    total = sum(a["cycles"] for a in rep["activity"].values()) + rep["sleep_cycles"]
    assert total == rep["cycles"]
    # One filter step per loop, one sample_estimate frame per loop in the window.
    assert rep["loops"] > 0 and abs(run.frames - rep["loops"]) <= 2, (run.frames, rep["loops"])
    assert run.frames_lost == 0 and run.uart_drops == 0
    assert 0 < rep["bus"]["occupancy"] < 1 and rep["bus"]["nacks"] == 0
    assert 0 < rep["stack_peak_bytes"] < 8192
    flash, ram = fw.image_size(_artefacts().image)
    assert flash > 10_000 and 0 < ram < 8192


def test_table_renders_and_bad_seconds_is_an_input_error(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    doc = {"image": "x.elf", "fixed_step_cycles": 15000, "float_step_cycles": 60000,
           "fixed_over_float": 0.25, "loop_rate_hz": 500.0, "idle_fraction": 0.3,
           "bus_occupancy": 0.4, "flash_bytes": 1000, "ram_bytes": 2000,
           "stack_peak_bytes": 600, "ram_plus_stack_bytes": 2600,
           "loop_cycles_per_loop": {"filter": 15000.0, "sleep": 9000.0},
           "loop": {"rate_hz": 500, "stale_frames": 0, "frames": 1000},
           "max_rate_hz": {"adxl345": {"max_rate_hz": 600, "tried": [
               {"rate_hz": 700, "sustained": False, "why": "3 overruns"}]}},
           "step_sections": {"updates": {"fixed": {"worst": 9000, "mean": 8800.0},
                                         "float": {"worst": 30000, "mean": 29000.0}}},
           "notes": ["a note"]}
    buf = io.StringIO()
    monkeypatch.setattr(bench_firmware, "Console", lambda: Console(file=buf, width=120))
    bench_firmware.print_table(doc)
    text = buf.getvalue()
    assert "15,000" in text and "at 700 Hz: 3 overruns" in text and "note: a note" in text
    assert "updates" in text and "29,000" in text  # the step's sections, when measured
    assert "NO" not in text
    # At a loop rate below the target, plenty of sleep and an idle bus do not count as met.
    buf.truncate(0)
    buf.seek(0)
    bench_firmware.print_table({**doc, "loop_rate_hz": 258.0})
    rows = {ln.split("│")[1].strip(): ln for ln in buf.getvalue().splitlines() if "│" in ln}
    assert "NO" in rows["idle (cycles asleep) at 258 Hz"]
    assert "NO" in rows["bus occupancy at 400 kHz at 258 Hz"]
    assert main(["bench", "firmware", "--seconds", "0"]) == 2
    assert "--seconds" in capsys.readouterr().err
