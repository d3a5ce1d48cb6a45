"""`live --host-filter`: a host estimator on the board's readings as they arrive.

The unit tests feed `HostFilter` board estimates made from a simulated motion (no board); the
end-to-end test runs `live` on sim://native against the motion's truth and against `estimate`
on the same CSV.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from cli_runs import LiveRun

from jointangle.cli.main import main
from jointangle.device.calibration_map import DeviceMaps, counts_from_readings, device_readings
from jointangle.estimators.base import wrap
from jointangle.estimators.registry import get_estimator
from jointangle.live import host_filter as hf
from jointangle.live.host_filter import HostEstimate, HostFilter, json_fields
from jointangle.live.session import Estimate
from jointangle.protocol import messages as msgs
from jointangle.rig import Rig
from jointangle.sim.scenarios import simulate

RATE = 200.0
FROZEN = int(msgs.SensorStatus.FROZEN)
RUNNING = int(msgs.FilterHealth.RUNNING)


def _board(seconds: float = 5.0) -> tuple[Rig, list[Estimate], np.ndarray]:
    """Board estimates (θ = the truth, the raw counts of the motion) and the truth (°)."""
    sim = simulate("gravity-fast-periodic", seed=2, rate_hz=RATE, seconds=seconds)
    counts = counts_from_readings(sim.rig, sim.readings)
    truth = np.degrees(sim.theta)
    n = counts.shape[1]
    ests = [Estimate(k / RATE, k, float(truth[k]), 0.0, 0.0, RUNNING, (0,) * n, k / RATE,
                     counts[k]) for k in range(counts.shape[0])]
    return sim.rig, ests, truth


def _run(host: HostFilter, ests: list[Estimate], batch: int = 7
         ) -> list[tuple[Estimate, HostEstimate | None]]:
    out = []
    for b in range(0, len(ests), batch):
        host.add(ests[b:b + batch])
        out += host.run(now=ests[min(b + batch, len(ests)) - 1].device_s)
    return out + host.finish()


@pytest.mark.parametrize("name", ["array-fls", "array-ekf", "smooth"])
def test_each_board_line_carries_the_host_estimate_lag_samples_before(name: str) -> None:
    rig, ests, _ = _board()
    host = HostFilter(name, rig)
    pairs = _run(host, ests)
    assert [e.seq for e, _ in pairs] == [e.seq for e in ests]
    lag = host.lag_samples
    assert lag == {"array-fls": 20, "array-ekf": 0, "smooth": 12}[name]
    # The batch estimator on the firmware's readings of the same counts.
    counts = np.stack([e.counts for e in ests if e.counts is not None])
    acc = device_readings(DeviceMaps.from_rig(rig), counts)
    whole = get_estimator(name).estimate(rig, acc[None])
    for k, (est, h) in enumerate(pairs):
        if k < lag:
            assert h is None
            continue
        assert h is not None
        assert h.device_t == pytest.approx(est.device_s - lag / RATE)
        assert abs(float(wrap(np.radians(h.theta_deg) - whole.theta[0, k - lag]))) < 1e-9
    assert host.estimates == host.samples == len(ests) and host.restarts == 0
    s = host.summary()
    assert s["name"] == name and s["lag_ms"] == pytest.approx(lag * 1000 / RATE)
    assert s["cpu_per_sample_ms"] > 0 and s["switched_off"] is None
    assert s["compared_samples"] > 0 and s["host_minus_board_rms_deg"] < 1.0


def test_a_gap_or_a_faulty_sensor_restarts_it() -> None:
    rig, ests, truth = _board(6.0)
    del ests[400:410]  # ten frames lost: the device clock jumps
    for e in ests[700:760]:  # a.0 frozen: one usable sensor left on link a
        e.sensor_status = (FROZEN, 0, 0, 0)
    host = HostFilter("array-ekf", rig)
    pairs = _run(host, ests)
    got = {round(e.device_s * RATE): h for e, h in pairs}
    assert all(got[k] is None for k in range(710, 770))  # (the gap shifted indices by 10)
    assert got[700] is not None and got[780] is not None
    assert host.restarts == 3 and host.estimates == len(ests) - 60
    # After each restart it locks on again.
    late = [h for e, h in pairs if h is not None and h.segment_s > 2.0]
    err = [abs(h.theta_deg - np.interp(h.device_t, np.arange(truth.size) / RATE, truth))
           for h in late]
    assert late and max(err) < 1.0


def test_it_is_switched_off_when_it_cannot_keep_up() -> None:
    rig, ests, _ = _board(4.0)
    clock = iter(np.arange(0.0, 1e4, 0.05))  # each batch "costs" 50 ms: 7 ms a 5 ms sample
    host = HostFilter("array-ekf", rig, cpu_clock=lambda: float(next(clock)))
    pairs = _run(host, ests)
    assert host.off is not None and "switched off" in host.off and "200 Hz" in host.off
    off_at = next(k for k, (_, h) in enumerate(pairs) if k > 10 and h is None)
    assert hf.WARMUP_S * RATE <= off_at < (hf.WARMUP_S + 0.1) * RATE
    assert all(h is None for _, h in pairs[off_at:])
    assert json_fields(host, None)["host_filter"] == "array-ekf"
    assert host.summary()["switched_off"] == host.off


def test_json_fields_without_a_host_filter_are_null() -> None:
    f = json_fields(None, None)
    assert set(f) == {"host_filter", "host_lag_ms", "host_device_t", "host_theta_deg",
                      "host_omega_a_dps", "host_omega_b_dps"}
    assert set(f.values()) == {None}


@pytest.mark.parametrize(("name", "why"), [("ekf", "whole run"), ("nope", "not a filter")])
def test_live_refuses_a_filter_without_a_streaming_form_in_one_line(
        name: str, why: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--host-filter", name, "--seconds", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--host-filter" in err and why in err
    assert "array-fls" in err


# The host filter's behaviour, not a board's: on the native board, whose readings the host's
# `estimate` rebuilds exactly (the Mega reads its sensors one after another on its batch).
@pytest.mark.parametrize("hil_port", ["sim://native"])
def test_live_host_filter_on_sim_native_matches_estimate_on_the_same_motion(
        sim_url: Callable[..., str], live_until: Callable[..., LiveRun], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The host's θ against the motion's truth is `estimate --filter array-fls`'s on the
    same CSV (read as the native board reads it: `--sensor-timing board:0`). In real time: a
    board faster than that (fast=1) outruns the host filter, which then switches itself off.
    At 200 Hz: the suite runs two workers on two cores, and at 500 Hz the estimator, sharing
    its core, fell behind and left most lines without a host value (948 of 4 350)."""
    rate = 200
    motion, rig = tmp_path / "motion.csv", tmp_path / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-fast-periodic", "--seed", "1", "--rate",
                 str(rate), "--seconds", "9", "--out", str(motion), "--rig-out", str(rig)]) == 0
    run = live_until(sim_url(motion=motion, rig=rig, loop=0), 8.8,
                     "--host-filter", "array-fls", "--no-mirror")
    host = run.summary["host_filter"]
    assert host["name"] == "array-fls" and host["lag_ms"] == 100.0
    assert host["switched_off"] is None and host["lost_track"] == 0
    assert all(r["host_filter"] == "array-fls" for r in run.rows)
    # (after the CSV's last row, 9 s, the board holds it: not the motion any more)
    rows = [r for r in run.rows if r["host_theta_deg"] is not None and r["device_t"] < 8.8]
    assert len(rows) > 0.9 * 8.7 * rate, host
    for r in rows:
        assert r["host_device_t"] == pytest.approx(r["device_t"] - 0.1, abs=1e-6)
    out = tmp_path / "est.csv"
    assert main(["estimate", "--rig", str(rig), "--input", str(motion), "--filter",
                 "array-fls", "--out", str(out), "--sensor-timing", "board:0"]) == 0
    capsys.readouterr()
    est = np.genfromtxt(out, delimiter=",", names=True)
    m = np.genfromtxt(motion, delimiter=",", names=True)
    t = np.array([r["host_device_t"] for r in rows])
    k = np.rint(t * rate).astype(int)
    steady = (t >= 5.0) & (t <= 8.6)
    host_th = np.array([r["host_theta_deg"] for r in rows])
    truth = np.degrees(m["theta"][k])

    def rms(e: np.ndarray) -> float:
        return float(np.sqrt(np.mean(((e + 180) % 360 - 180)[steady] ** 2)))

    rms_host, rms_est = rms(host_th - truth), rms(est["theta_deg"][k] - truth)
    print(f"\nθ RMS vs truth, t in [5, 8.6] s: live host array-fls {rms_host:.5f}°, estimate "
          f"{rms_est:.5f}°; CPU {host['cpu_per_sample_ms']:.3f} ms a sample")
    assert rms_host == pytest.approx(rms_est, rel=0.05)
    # From a few seconds in, the two are the same filter on the same readings.
    assert np.max(np.abs((host_th - est["theta_deg"][k] + 180) % 360 - 180)[steady]) < 0.01
    json.dumps(run.summary)  # the summary is plain JSON


def test_record_summarises_the_host_filter_and_replay_adds_its_columns(
        sim_url: Callable[..., str], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    rec = tmp_path / "run.jrec"
    # (in real time: a board faster than that would outrun it, and it would switch off; 5 s:
    # host - board is taken after each filter start's first 2 s, empty in a 2 s recording, and
    # a slow board's, the Pico emulator's, filter starts later into the recording)
    assert main(["record", "--port", sim_url(), "--seconds", "5", "--out", str(rec),
                 "--host-filter", "array-ekf", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    host = doc["host_filter"]
    assert host["name"] == "array-ekf" and host["lag_ms"] == 0.0
    assert host["samples"] == doc["samples"] and host["estimates"] == doc["samples"] > 500
    assert host["host_minus_board_rms_deg"] is not None and host["cpu_per_sample_ms"] > 0
    # replay: the same filter from the recording gives the same numbers as it did live.
    csv = tmp_path / "est.csv"
    assert main(["replay", str(rec), "--estimates-csv", str(csv), "--host-filter",
                 "array-ekf", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    # (Two segments when the stream also caught the board's own first filter start, which
    # happens when start_stream lands before the board's first step: a slow board, the Pico's
    # emulator, or a loaded machine.)
    assert rep["host_filter"] == "array-ekf" and rep["host_segments"] in (1, 2), rep
    assert rep["host_rows"] == rep["estimate_rows"] == doc["samples"]
    table = np.genfromtxt(csv, delimiter=",", names=True)
    names = table.dtype.names
    assert names is not None
    assert names[-3:] == ("host_theta_deg", "host_omega_a_dps", "host_omega_b_dps")
    assert table["host_theta_deg"][-1] == pytest.approx(host["theta_deg"], abs=1e-5)
    # an offline filter too, from the same recording
    assert main(["replay", str(rec), "--estimates-csv", str(tmp_path / "rts.csv"),
                 "--host-filter", "array-rts", "--json"]) == 0
    rts = np.genfromtxt(tmp_path / "rts.csv", delimiter=",", names=True)
    assert np.isfinite(rts["host_theta_deg"]).all()
    d = (rts["host_theta_deg"] - table["host_theta_deg"] + 180) % 360 - 180
    assert np.sqrt(np.mean(d[500:] ** 2)) < 0.2


@pytest.mark.parametrize(("argv", "needle"), [
    (["record", "--port", "sim://native", "--seconds", "1", "--out", "x.jrec",
      "--host-filter", "ukf"], "whole run"),
    (["replay", "x.jrec", "--host-filter", "array-fls"], "--estimates-csv"),
    (["replay", "x.jrec", "--estimates-csv", "e.csv", "--host-filter", "nope"], "nope"),
])
def test_bad_host_filter_options_are_one_line(argv: list[str], needle: str, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.jrec").write_bytes(b"")
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--host-filter" in err and needle in err, err


def test_view_shows_the_host_theta_beside_the_boards_and_fits_80x24(
        fake_data: tuple[object, str]) -> None:
    import io

    from rich.console import Console
    from test_live import _state

    from jointangle.live.view import render

    state = _state(fake_data, 600, observable=False)  # type: ignore[arg-type]
    assert state.rig is not None
    host = HostFilter("array-fls", state.rig)
    texts = []
    for latest in (None, HostEstimate(1.0, -12.3456, -98.76, 123.45, 1.0)):
        host.latest = latest
        buf = io.StringIO()
        console = Console(file=buf, width=80, height=24, force_terminal=True, color_system=None)
        console.print(render(state, port="/dev/pts/7", recording="x.jrec", rec_seconds=3.0,
                             stats={"frames": 600, "frames_lost": 2, "crc_errors": 1},
                             message="device lost (port error); reconnecting", host=host))
        lines = buf.getvalue().splitlines()
        assert len(lines) <= 24
        assert all(console.measure(line).maximum <= 80 for line in lines)
        texts.append(buf.getvalue())
    assert "array-fls" in texts[0] and "waiting for 100 ms of samples" in texts[0]
    assert "array-fls θ   -12.346°  ω_a   -98.8  ω_b   123.5  100 ms behind" in texts[1]
    assert "firmware − mirror: max |Δθ|" in texts[1] and "REC x.jrec" in texts[1]
    buf = io.StringIO()
    Console(file=buf, width=80, color_system=None).print(
        render(state, port="p", host=None, host_word="host filter off: needs the rig (--rig)"))
    assert "host filter off: needs the rig" in buf.getvalue()


def test_replay_host_columns_run_each_segment_on_its_own(
        fake_data: tuple[object, str]) -> None:
    """Frames lost, or a sensor frozen, start a new segment; a segment without two usable
    sensors per link has no estimate; the rest equal the estimator on each segment alone."""
    from fake_device import FakeData

    from jointangle.device.rig import device_rig
    from jointangle.recording.host_columns import host_columns
    from jointangle.rig import parse_rig

    data, rig_text = fake_data
    assert isinstance(data, FakeData)
    T = 1200
    keep = np.r_[0:500, 510:T]  # frames 500..509 lost
    status = np.zeros((T, len(data.sensors)), dtype=np.int64)
    status[800:900, 0] = FROZEN
    period = round(1e6 / data.rate_hz)
    cols = {"t_us": (np.arange(T) * period)[keep].astype(np.uint32),
            "sensors.x": data.counts[:T, :, 0][keep], "sensors.y": data.counts[:T, :, 1][keep],
            "sensors.z": data.counts[:T, :, 2][keep], "sensors.status": status[keep]}
    lost = np.zeros(keep.size, dtype=np.int64)
    lost[500] = 10
    hello = msgs.Hello(1, msgs.SCHEMA_HASH, 0, 9, 1, b"fake", msgs.Board.NATIVE, data.rate_hz,
                       4, 0, data.sensors)
    rig = parse_rig(rig_text)
    got = host_columns(rig, hello, cols, lost, "array-ekf")
    assert got.segments == 4 and len(got.refused) == 1
    assert "rows 790-889: fewer than two usable sensors" in got.refused[0]
    assert np.isnan(got.values[790:890]).all() and np.isfinite(np.delete(
        got.values, np.s_[790:890], axis=0)).all()
    # the segment after the gap starts afresh: the estimator on those rows alone
    drig = device_rig(rig, hello)
    acc = device_readings(DeviceMaps.from_rig(drig), np.stack(
        [cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2)[500:790])
    alone = get_estimator("array-ekf").estimate(drig, acc[None])
    np.testing.assert_allclose(got.values[500:790, 0], np.degrees(alone.theta[0]), atol=1e-9)


def test_lines_keep_the_boards_pace_when_the_host_falls_behind() -> None:
    from jointangle.live.host_worker import LINE_WAIT_S, HostLines

    class Stalled:  # a worker that has not got round to anything yet
        def __init__(self) -> None:
            self.queued: list[Estimate] = []

        def add(self, ests: list[Estimate]) -> None:
            self.queued += ests

        def take(self) -> list[tuple[Estimate, HostEstimate | None]]:
            return []

        def finish(self) -> list[tuple[Estimate, HostEstimate | None]]:
            return [(e, HostEstimate(e.device_s, 1.0, 0.0, 0.0, 0.0)) for e in self.queued]

    _, ests, _ = _board(2.0)
    worker = Stalled()
    lines = HostLines(worker)  # type: ignore[arg-type]
    out = []
    for b in range(0, len(ests), 10):
        out += lines.feed(ests[b:b + 10])
        if out:  # never more than LINE_WAIT_S (+ one feed) behind the newest
            assert ests[b + 9].device_s - out[-1][0].device_s <= LINE_WAIT_S + 10 / RATE
    assert all(h is None for _, h in out) and lines.without_host == len(out) > 300
    rest = lines.finish()
    assert [e.seq for e, _ in out + rest] == [e.seq for e in ests]
    assert all(h is not None for _, h in rest)  # the late results go to the lines still waiting


@pytest.mark.parametrize("hil_port", ["sim://native"])  # (faster than any host filter)
def test_a_board_faster_than_real_time_switches_the_host_filter_off(
        sim_url: Callable[..., str], live_until: Callable[..., LiveRun]) -> None:
    run = live_until(sim_url(fast=1), 20.0, "--host-filter", "array-fls", "--no-mirror")
    host = run.summary["host_filter"]
    assert host["switched_off"] is not None and "waited for it" in host["switched_off"]
    assert "switched off" in run.stderr
    assert run.rows[-1]["device_t"] >= 20.0 and run.summary["frames_lost"] == 0
    assert host["lines_without_host"] > 0
