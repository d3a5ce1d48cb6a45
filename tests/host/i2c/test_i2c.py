"""The smbus2 driver (jointangle.i2c) against the virtual devices: register sequences of every
part, calibration, the streaming EKF, NACK and mux read-back faults, `live --i2c`, bench host."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from jointangle.boards.sim_devices import Fault, SimSMBus, VirtualBus
from jointangle.cli.main import main
from jointangle.device.calibration_map import mps2_per_count
from jointangle.errors import InputError
from jointangle.estimators.base import sensor_to_link
from jointangle.estimators.paper import PaperEKF
from jointangle.i2c.bus import SIM_SCL_HZ, OpenBus, open_bus, sim_bus
from jointangle.i2c.pipeline import I2cPipeline, StreamingEKF, calibration_maps
from jointangle.protocol import messages as msgs
from jointangle.rig import Rig, parse_rig
from jointangle.sim.scenarios import gravity_rig, simulate

MIXED_RIG = """\
name = "mixed"
sample_rate_hz = 200
[links.a]
joint = [0.30, 0.0]
[[links.a.sensors]]
model = "adxl345"
position = [0.25, 0.0]
mux_channel = 0
address = 0x53
range_g = 4
[[links.a.sensors]]
model = "adxl357"
position = [0.05, 0.0]
rotation_deg = 90.0
mux_channel = 1
address = 0x1D
range_g = 10
[links.b]
joint = [0.0, 0.0]
[[links.b.sensors]]
model = "bno055"
position = [0.05, 0.0]
mux_channel = 2
address = 0x28
range_g = 4
[[links.b.sensors]]
model = "adxl345"
position = [0.25, 0.0]
mux_channel = 3
address = 0x53
range_g = 2
S = [[1.01, 0.002, 0.0], [0.0, 0.99, 0.01], [0.0, 0.0, 1.0]]
offset = [0.05, -0.02, 0.1]
"""


def _fake(rig: Rig) -> OpenBus:
    """The virtual parts of `rig`, not paced (device time advances by the bus time only)."""
    vb = VirtualBus(scl_hz=SIM_SCL_HZ)
    vb.attach_rig(rig)
    return OpenBus(SimSMBus(vb), "test", vb)


def test_every_part_is_configured_and_read_through_the_mux() -> None:
    rig = parse_rig(MIXED_RIG)
    ob = _fake(rig)
    forces = [(1.0, -2.0, 9.0), (3.5, 0.25, -8.0), (-4.0, 6.0, 2.0), (0.3, -0.6, 9.7)]
    for k, (ln, i, _) in enumerate(rig.all_sensors()):
        ob.virtual.set_constant_motion(ob.virtual.find_device(f"{ln}.{i}"), forces[k])
    p = I2cPipeline(ob.bus, rig)
    p.configure()
    assert p.status == [0, 0, 0, 0], p.errors
    for _ in range(5):
        ob.virtual.advance_us(5000)  # new samples (ODR) between steps
        st = p.step()
    # The BNO055 has no data-ready: a repeated value (constant motion) is not fresh.
    assert st.fresh == (True, True, False, True) and st.theta_deg is not None
    for k, (_, _, s) in enumerate(rig.all_sensors()):
        lsb = float(mps2_per_count(s.model, s.range_g))
        np.testing.assert_allclose(p.counts[k] * lsb, forces[k], atol=1.01 * lsb)
    for dev in range(ob.virtual.device_count):
        assert ob.virtual.device_counters(dev).config_violations == 0
    # One combined transaction per register read: as many repeated STARTs as transactions
    # minus the plain writes.
    c = ob.virtual.bus_counters()
    assert c.repeated_starts > 0 and c.bus_errors == 0


def test_calibration_maps_are_sensor_to_link() -> None:
    rig = parse_rig(MIXED_RIG)
    rng = np.random.default_rng(1)
    counts = rng.integers(-3000, 3000, size=(4, 3)).astype(float)
    m, b = calibration_maps(rig)
    lsb = np.array([float(mps2_per_count(s.model, s.range_g))
                    for _, _, s in rig.all_sensors()])
    want = sensor_to_link(rig, (counts * lsb[:, None])[None])[0]
    got = (np.einsum("nij,nj->ni", m, counts) + b).reshape(-1)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_streaming_ekf_is_the_batch_ekf() -> None:
    sim = simulate("gravity-slow-periodic", seed=2, rate_hz=200.0, seconds=2.0)
    acc = sensor_to_link(sim.rig, sim.readings)
    batch = PaperEKF().estimate(sim.rig, acc[None])
    ekf = StreamingEKF(sim.rig)
    xs = np.array([ekf.step(a) for a in acc])
    np.testing.assert_allclose(xs[:, 0], batch.omega_a[0], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (xs[:, 2] - batch.theta[0]))), 0,
                               atol=1e-9)


def test_nack_sets_the_flag_names_the_part_and_recovers() -> None:
    rig = gravity_rig(200.0)
    ob = _fake(rig)
    p = I2cPipeline(ob.bus, rig, probe_interval_s=0.0)
    p.configure()
    ob.virtual.advance_us(5000)
    assert p.step().theta_deg is not None
    dev = ob.virtual.find_device("a.1")
    ob.virtual.inject_fault(dev, Fault.NACK)
    st = p.step()
    assert st.status[1] & msgs.SensorStatus.NACK and not st.status[0]
    assert st.theta_deg is None  # one usable sensor left on link a: no estimate
    assert any("sensor a.1 (adxl345 at 0x53, mux channel 1)" in e and "no acknowledge" in e
               for e in p.errors), p.errors
    assert p.nacks[1] >= 1
    ob.virtual.clear_fault(dev)
    ob.virtual.advance_us(5000)
    p.step()  # re-probed (configured again) at once: probe_interval_s = 0
    ob.virtual.advance_us(5000)
    st = p.step()
    assert st.status == (0, 0, 0, 0) and st.theta_deg is not None
    assert p.filter_resets >= 3  # start, the fault, the recovery


def test_mux_readback_mismatch_is_detected() -> None:
    rig = gravity_rig(200.0)
    ob = _fake(rig)
    p = I2cPipeline(ob.bus, rig, probe_interval_s=1e9)
    p.configure()
    mux = next(d for d in range(ob.virtual.device_count)
               if ob.virtual.device_info(d)[1] == 0x70)
    ob.virtual.inject_fault(mux, Fault.WRONG_ID, 0x40)  # control register reads back ^ 0x40
    st = p.step()
    assert all(s & msgs.SensorStatus.NACK for s in st.status)
    assert p.mux is not None and p.mux.mismatches == 4
    assert any("control register reads back" in e for e in p.errors), p.errors


def test_fake_bus_charges_real_400_khz_time() -> None:
    rig = gravity_rig(200.0)
    ob = sim_bus(rig, seconds=1.0)  # realtime
    p = I2cPipeline(ob.bus, rig)
    p.configure()
    bits0 = ob.virtual.bus_counters().scl_bits
    t0 = time.perf_counter()
    for _ in range(40):
        p.step()
    wall = time.perf_counter() - t0
    bits = ob.virtual.bus_counters().scl_bits - bits0
    ob.close()
    # 4 × (mux select + read-back: 39 bits; INT_SOURCE..DATAZ1: 102 bits) per step.
    assert bits == 40 * 4 * (39 + 102)
    assert wall >= bits / SIM_SCL_HZ - 0.0011  # the bus time was spent (a quantum may be owed)


def test_bus_argument_errors() -> None:
    rig = gravity_rig(200.0)
    with pytest.raises(InputError, match="/dev/i2c-97"):
        open_bus("97", rig)
    with pytest.raises(InputError, match="bus number"):
        open_bus("i2c1", rig)


def test_live_i2c_sim_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--i2c", "sim", "--seconds", "1", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["steps"] > 10 and doc["rate_hz"] > 0 and doc["errors"] == []
    assert all(v > 0 for v in doc["stage_us"].values())
    assert [s["status"] for s in doc["sensors"]] == [[]] * 4
    assert doc["theta_deg"] is not None


def test_live_real_bus_needs_the_rig(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--i2c", "1", "--seconds", "1"]) == 2
    assert "--rig" in capsys.readouterr().err


def test_bench_host_json_shape(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "host", "--json", "--seconds", "0.5"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sensors"] == 4 and doc["faults"] == 0 and doc["rate_hz"] > 0
    assert set(doc["stage_us"]) == {"bus", "conversion_calibration", "filter"}
    assert all(v > 0 for v in doc["stage_us"].values())
    assert doc["bus_time_us"] == pytest.approx(4 * (39 + 102) / SIM_SCL_HZ * 1e6)
    assert doc["transactions_per_step"] == 8


def test_the_i2c_path_tracks_the_simulated_joint_angle() -> None:
    """Motion → virtual parts → smbus2 driver → calibration → EKF, stepped in device time:
    the joint angle follows the simulation's truth (decoding, axes and signs all right)."""
    rig = gravity_rig(200.0)
    sim = simulate("gravity-slow-periodic", seed=0, rate_hz=200.0, seconds=6.0, rig=rig)
    ob = _fake(rig)
    for k, name in enumerate(f"{ln}.{i}" for ln, i, _ in rig.all_sensors()):
        ob.virtual.set_motion(name, sim.t, sim.readings[:, k, :])
    p = I2cPipeline(ob.bus, rig)
    p.configure()
    theta = []
    for t in sim.t:
        ob.virtual.set_time_us(t * 1e6 + 100.0)
        st = p.step()
        assert st.theta_deg is not None
        theta.append(st.theta_deg)
    err = (np.asarray(theta) - np.degrees(sim.theta) + 180.0) % 360.0 - 180.0
    rms = float(np.sqrt(np.mean(err[400:] ** 2)))  # after the 2 s start-up
    assert rms < 0.5, rms  # measured 0.10° (the float EKF on exact readings: 0.04°)


@pytest.mark.parametrize("extra", [["--record", "x.jrec"], ["--port", "sim://native"],
                                   ["--no-mirror"]])
def test_live_i2c_refuses_the_options_of_a_board_stream(
        extra: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["live", "--i2c", "sim", "--seconds", "1", *extra]) == 2
    err = capsys.readouterr().err
    assert extra[0] in err and "--i2c" in err and err.count("\n") == 1
