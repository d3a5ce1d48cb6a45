"""HIL: the stream contents the host chooses (issue 17, item 3) — `--stream estimates` (the
board's lean_estimate frames: estimate, health, fault mask) fits a 115 200 baud link where the
full frame does not, counts losses as the full stream does, and says plainly what it cannot do
(no verification, no host filter); `--every N` thins the per-loop frames."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from cli_runs import LiveRun

from jointangle.cli.main import main


def replay_json(capsys: pytest.CaptureFixture[str], path: Path) -> dict:
    capsys.readouterr()
    assert main(["replay", str(path), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_estimates_fit_a_115200_baud_link_where_full_frames_do_not(
        sim_url: Callable[..., str], live_until: Callable[..., LiveRun]) -> None:
    url = sim_url(fast=1, baud=115_200, rate=250)
    lean = live_until(url, 4.0, "--stream", "estimates")
    s = lean.summary
    assert s["frames_lost"] == 0 and s["uart_drops"] == 0, s
    assert s["sample_rate_hz"] == pytest.approx(250, rel=0.02), s
    assert s["host_filter"] is None and s["max_abs_dtheta_deg"] is None  # nothing to run them on
    assert all(r["theta_deg"] is not None for r in lean.rows[-100:])
    full = live_until(url, 4.0).summary
    assert full["frames_lost"] > 0.2 * (full["frames"] + full["frames_lost"]), full


# 115 200 baud carries 11 520 bytes a second: lean_estimate frames (27 bytes framed) and a
# status every 200 ms fit up to ~400 loops a second; the native board sustains more than that.
LEAN_115200_MAX_HZ = 300


def test_60_s_of_estimates_at_115200_baud_at_the_sustainable_rate_lose_nothing(
        sim_url: Callable[..., str], live_until: Callable[..., LiveRun],
        capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 17, acceptance: the board's own sustainable rate with the lean stream (`info
    --rates --stream estimates`), then 60 s of it at 115 200 baud: 0 frames lost, 0 UART
    drops, the rate held."""
    capsys.readouterr()
    assert main(["info", "--port", sim_url(fast=1, baud=115_200), "--rates", "--stream",
                 "estimates", "--json"]) == 0
    sustainable = json.loads(capsys.readouterr().out)["sustainable_rate_hz"]
    rate = min(sustainable, LEAN_115200_MAX_HZ)
    s = live_until(sim_url(fast=1, baud=115_200, rate=rate), 60.0, "--stream",
                   "estimates").summary
    print(f"\n{sim_url()}: sustainable {sustainable} Hz with the lean stream; 60 s at {rate} Hz "
          f"and 115 200 baud: {s['frames']} frames, {s['frames_lost']} lost, {s['uart_drops']} "
          f"UART drops")
    assert (s["frames_lost"], s["uart_drops"], s["crc_errors"]) == (0, 0, 0), s
    assert s["sample_rate_hz"] == pytest.approx(rate, rel=0.01), s
    assert s["frames"] >= 0.95 * 60 * rate, s


def test_a_lean_or_thinned_recording_counts_and_refuses_verification(
        sim_url: Callable[..., str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec = tmp_path / "lean.jrec"
    assert main(["record", "--port", sim_url(fast=1), "--stream", "estimates", "--every", "2",
                 "--seconds", "1.5", "--out", str(rec)]) == 0
    doc = replay_json(capsys, rec)
    assert doc["messages"].get("lean_estimate", 0) > 0, doc
    assert "sample_estimate" not in doc["messages"], doc
    assert doc["frames_lost"] == 0 and doc["duplicates"] == 0, doc
    capsys.readouterr()
    assert main(["replay", str(rec), "--verify"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--stream estimates --every 2" in err, err


def test_every_n_thins_the_full_stream(sim_url: Callable[..., str],
                                       live_until: Callable[..., LiveRun]) -> None:
    url = sim_url(fast=1, rate=200)
    s = live_until(url, 3.0, "--every", "4").summary
    assert s["sample_rate_hz"] == pytest.approx(200 / 4, rel=0.03), s
    assert s["frames_lost"] == 0 and s["max_abs_dtheta_deg"] is None, s


def test_a_host_filter_with_the_lean_stream_is_one_line_error(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--port", "sim://native", "--stream", "estimates", "--host-filter",
                 "array-fls", "--json", "--seconds", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--stream full --every 1" in err, err
