"""jointangle.sim.sensor_timing: readings rebuilt as the board's loop reads its sensors (each
sensor's latest conversion on its ODR grid, the CSV interpolated there, rounded to counts), and
`jointangle estimate --sensor-timing`."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from jointangle.cli.main import main
from jointangle.errors import InputError
from jointangle.estimators.analytical import Analytical
from jointangle.estimators.base import sensor_to_link
from jointangle.io.csv_formats import AccelData, read_accel_csv, write_accel_csv
from jointangle.io.rig_file import write_rig
from jointangle.sim.scenarios import gravity_rig
from jointangle.sim.sensor_timing import (
    SensorTiming,
    board_readings,
    conversion_instants,
    odr_period_ns,
    parse_sensor_timing,
    part_clock,
)

RATE = 500.0
LSB = 0.0039 * 9.80665  # ADXL345 full resolution, m/s² per count


def ramp(n: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Rows t_k = 2 ms·k; every axis of every sensor reads 4 counts per row (2 counts per ms),
    x rising, y falling, z constant 100 counts."""
    t = np.arange(n) * (1.0 / RATE)
    r = np.zeros((n, 4, 3))
    r[:, :, 0] = (4.0 * np.arange(n) * LSB)[:, None]
    r[:, :, 1] = -r[:, :, 0]
    r[:, :, 2] = 100.0 * LSB
    return t, r


def test_odr_the_firmware_chooses_per_model_and_rate() -> None:
    # ADXL345: slowest of 100 .. 3200 Hz with ODR >= 1.6·rate; 800 Hz at 500 Hz.
    assert odr_period_ns("adxl345", 500) == 1_250_000
    assert odr_period_ns("adxl345", 100) == 5_000_000  # 200 Hz
    assert odr_period_ns("adxl345", 10) == 10_000_000  # 100 Hz, the slowest code
    assert odr_period_ns("adxl345", 1000) == 625_000  # 1600 Hz
    assert odr_period_ns("adxl345", 2500) == 312_500  # capped at 3200 Hz
    # ADXL357: 62.5 .. 4000 Hz; 1 kHz at 500 Hz, 500 Hz exactly at 312.5 Hz (1.6·312.5 = 500).
    assert odr_period_ns("adxl357", 500) == 1_000_000
    assert odr_period_ns("adxl357", 312.5) == 2_000_000
    assert odr_period_ns("bno055", 500) == 2_000_000  # 250 Hz bandwidth: a conversion per 2 ms
    with pytest.raises(InputError, match="mpu6050"):
        odr_period_ns("mpu6050", 500)


def test_conversion_instants_on_the_odr_grid_from_device_time_0() -> None:
    t, _ = ramp(6)
    # 800 Hz: latest j·1.25 ms at or before 2k ms.
    assert np.allclose(conversion_instants(t, 1_250_000, 0.0) * 1e3,
                       [0.0, 1.25, 3.75, 5.0, 7.5, 10.0], atol=1e-12)
    # read one period earlier (the AVR's pipelining): at 2(k−1) ms, device time 0 at the start.
    assert np.allclose(conversion_instants(t, 1_250_000, 1.0 / RATE) * 1e3,
                       [0.0, 0.0, 1.25, 3.75, 5.0, 7.5], atol=1e-12)
    # a loop grid 1 ms after the rows (L = −0.5): reads at 2k + 1 ms.
    assert np.allclose(conversion_instants(t, 1_250_000, -0.5 / RATE) * 1e3,
                       [0.0, 2.5, 5.0, 6.25, 8.75, 10.0], atol=1e-12)
    # 0.15 period into loop k−1 (0.3 ms): the conversion at 2(k−1) + 0.3 ms.
    assert np.allclose(conversion_instants(t, 1_250_000, 0.85 / RATE) * 1e3,
                       [0.0, 0.0, 1.25, 3.75, 6.25, 7.5], atol=1e-12)


def test_board_readings_interpolate_at_the_latest_conversion_and_round_to_counts() -> None:
    rig = gravity_rig(RATE)
    t, r = ramp(6)
    counts = board_readings(rig, t, r) / LSB
    # x = 2 counts/ms at 0, 1.25, 3.75, 5, 7.5, 10 ms = 0, 2.5, 7.5, 10, 15, 20: halves rounded
    # away from zero (3, 8), y the same negated (−3, −8); z unchanged.
    assert np.array_equal(np.rint(counts[:, 0, 0]), [0, 3, 8, 10, 15, 20])
    assert np.array_equal(np.rint(counts[:, 3, 1]), [0, -3, -8, -10, -15, -20])
    assert np.allclose(counts[:, :, 2], 100.0)
    assert np.allclose(counts, np.rint(counts), atol=1e-9)  # whole counts
    # board:1: read a period earlier, the first two loops take the first row.
    late = board_readings(rig, t, r, latency_periods=1.0) / LSB
    assert np.array_equal(np.rint(late[:, 1, 0]), [0, 0, 3, 8, 10, 15])
    # rows from 0.5 ms: the conversion at 0 holds the first row, at 2.5 ms is row 1 (4), at
    # 3.75 ms is 4 + 0.625·4 = 6.5 → 7.
    assert np.array_equal(np.rint(board_readings(rig, t[:3] + 0.0005, r[:3])[:, 0, 0] / LSB),
                          [0, 4, 7])
    # rows timing would be the rows themselves: 0, 4, 8, ... — the board's differ.
    assert not np.allclose(counts[:, 0, 0], r[:, 0, 0] / LSB)


def test_board_readings_read_each_sensor_a_spacing_after_the_one_before() -> None:
    rig = gravity_rig(RATE)
    t, r = ramp(6)
    spaced = board_readings(rig, t, r, latency_periods=1.0, read_spacing_s=1.25e-3)
    for i in range(4):  # sensor i read i·S later: its latency i·S·rate periods shorter
        alone = board_readings(rig, t, r, latency_periods=1.0 - i * 1.25e-3 * RATE)
        assert np.array_equal(spaced[:, i], alone[:, i])
    together = board_readings(rig, t, r, latency_periods=1.0)
    assert np.array_equal(spaced[:, 0], together[:, 0])
    assert not np.array_equal(spaced[:, 3], together[:, 3])


def test_a_part_on_its_own_clock_converts_at_its_offset_and_period() -> None:
    fast = replace(gravity_rig(RATE).links["a"].sensors[0], sim_clock_ppm=25_000.0,
                   sim_clock_phase=0.5)
    # 800 Hz nominal (1.25 ms) 2.5 % fast: P = ⌊1 250 000 / 1.025 + ½⌋ = 1 219 512 ns,
    # O = ⌊0.5·P + ½⌋ = 609 756 ns; in step (no fields) the nominal grid from 0.
    assert part_clock(fast, 1_250_000) == (1_219_512, 609_756)
    slow = replace(fast, sim_clock_ppm=-10_000.0, sim_clock_phase=0.0)
    assert part_clock(slow, 1_250_000) == (1_262_626, 0)
    assert part_clock(gravity_rig(RATE).links["a"].sensors[0], 1_250_000) == (1_250_000, 0)
    t, _ = ramp(6)  # reads at 0, 2, 4, 6, 8, 10 ms
    got = conversion_instants(t, 1_219_512, 0.0, 609_756) * 1e9
    # O + jP: 0.610, 1.829, 3.049, 4.268, 5.488, 6.707, 7.927, 9.146 ms; before O the first.
    assert np.array_equal(np.rint(got), [609_756, 1_829_268, 3_048_780, 5_487_804,
                                         7_926_828, 9_146_340])
    rig = gravity_rig(RATE)
    _, r = ramp(6)
    clocked = replace(rig, links={**rig.links, "a": replace(rig.links["a"], sensors=(
        fast, rig.links["a"].sensors[1]))})
    counts = board_readings(clocked, t, r) / LSB
    # x = 2 counts/ms at those instants: 1.2, 3.7, 6.1, 11.0, 15.9, 18.3 → rounded.
    assert np.array_equal(np.rint(counts[:, 0, 0]), [1, 4, 6, 11, 16, 18])
    assert np.array_equal(counts[:, 1:], board_readings(rig, t, r)[:, 1:] / LSB)


def test_board_readings_clamp_to_the_parts_range() -> None:
    rig = gravity_rig(RATE)  # ADXL345 ±2 g: counts −512 .. 511
    t, r = ramp(4)
    r[:, 0, 0] = 3.0 * 9.80665
    r[:, 0, 1] = -3.0 * 9.80665
    out = board_readings(rig, t, r) / LSB
    assert np.allclose(out[:, 0, 0], 511) and np.allclose(out[:, 0, 1], -512)


def test_parse_sensor_timing() -> None:
    assert parse_sensor_timing("rows") == SensorTiming("rows", 0.0)
    assert parse_sensor_timing("board") == SensorTiming("board", 0.0)
    assert parse_sensor_timing("board:1") == SensorTiming("board", 1.0)
    assert parse_sensor_timing("board:0.5").latency_periods == 0.5
    assert parse_sensor_timing("board:-0.4").latency_periods == -0.4
    assert parse_sensor_timing("board:0.4:286") == SensorTiming("board", 0.4, 286e-6)
    for bad in ("board:x", "rows:1", "avr", "board:nan", "board:inf", "board:", "board:1:",
                "board:1:-5", "board:1:x", "board:1:2:3"):
        with pytest.raises(InputError, match="--sensor-timing"):
            parse_sensor_timing(bad)


def test_estimate_cli_runs_the_filter_on_the_board_timed_readings(
        tmp_path: Path) -> None:
    rig = gravity_rig(RATE)
    n = 400
    t = np.arange(n) / RATE
    rng = np.random.default_rng(3)
    r = np.zeros((n, 4, 3))
    ang = 0.3 * np.sin(2 * np.pi * 1.0 * t)
    r[:, :2, 0] = 9.80665
    r[:, 2:, 0] = (9.80665 * np.cos(ang))[:, None]
    r[:, 2:, 1] = (9.80665 * np.sin(ang))[:, None]
    r = np.round((r + 0.02 * rng.standard_normal(r.shape)) / LSB) * LSB
    csv, rig_path = tmp_path / "in.csv", tmp_path / "rig.toml"
    write_accel_csv(csv, rig, AccelData(t, r))
    write_rig(rig, rig_path)
    outs = {}
    for timing in ("rows", "board"):
        out = tmp_path / f"{timing}.csv"
        assert main(["estimate", "--rig", str(rig_path), "--input", str(csv), "--filter",
                     "analytical", "--out", str(out), "--sensor-timing", timing]) == 0
        outs[timing] = np.genfromtxt(out, delimiter=",", names=True)["theta_deg"]
    # analytical is per sample: board timing = eq. 12 on board_readings of the CSV as read.
    data = read_accel_csv(csv, rig)
    b = board_readings(rig, data.t, data.readings)
    expect = np.degrees(Analytical().estimate(rig, sensor_to_link(rig, b)[None]).theta[0])
    assert np.allclose(outs["board"], expect, atol=1e-6)
    assert not np.allclose(outs["rows"], outs["board"], atol=1e-3)
    assert main(["estimate", "--rig", str(rig_path), "--input", str(csv), "--filter",
                 "analytical", "--out", str(tmp_path / "x.csv"), "--sensor-timing",
                 "board:x"]) == 2


def test_adxl345_at_1600_hz_outputs_even_counts() -> None:
    # 1000 Hz loop: ODR 1600 Hz (0.625 ms), where the part's LSB reads 0 (bit 0 cleared).
    rig = gravity_rig(1000.0)
    t = np.arange(4) / 1000.0
    r = np.zeros((4, 4, 3))
    r[:, :, 0] = (5.0 * np.arange(4) * LSB)[:, None]  # 5 counts per ms
    r[:, :, 1] = -r[:, :, 0]
    c = np.rint(board_readings(rig, t, r) / LSB)
    # conversions at 0, 0.625, 1.875, 2.5 ms: 0, 3.125, 9.375, 12.5 → 0, 3, 9, 13 → 0, 2, 8, 12
    assert np.array_equal(c[:, 0, 0], [0, 2, 8, 12])
    assert np.array_equal(c[:, 0, 1], [0, -4, -10, -14])  # −3 → −4 in two's complement
    # at 500 Hz (800 Hz ODR) odd counts stay: test above (3, 8, ...).
