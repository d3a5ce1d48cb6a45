"""The virtual I2C devices through their C ABI (jointangle.boards.sim_devices): smbus2-style
transactions against motion from `jointangle simulate`, the multiplexer, the other parts,
faults, bus time."""

from __future__ import annotations

import errno
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from smbus2 import i2c_msg

from jointangle.boards.sim_devices import (
    BusCounters,
    Fault,
    I2cNackError,
    I2cResult,
    Model,
    SimSMBus,
    VirtualBus,
    find_library,
    rig_spec,
)
from jointangle.cli.main import main
from jointangle.errors import InputError
from jointangle.io.csv_formats import read_accel_csv
from jointangle.io.rig_file import load_rig

G = 9.80665
ADXL345_LSB = 0.0039 * G  # full resolution, m/s²
MUX = 0x70


@pytest.fixture(scope="module")
def library() -> Path:
    return find_library()


@pytest.fixture
def simulated(tmp_path: Path) -> tuple[Path, Path]:
    csv, rig = tmp_path / "data.csv", tmp_path / "rig.toml"
    assert main(["simulate", "--scenario", "gravity-fast-periodic", "--seconds", "2", "--out",
                 str(csv), "--rig-out", str(rig)]) == 0
    return csv, rig


def _le16(b: bytes, i: int) -> int:
    return int.from_bytes(b[i:i + 2], "little", signed=True)


def test_find_library_reports_a_missing_override(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("JOINTANGLE_SIMDEV_LIB", "/nonexistent/libja_sim_devices.so")
    with pytest.raises(InputError, match="JOINTANGLE_SIMDEV_LIB"):
        find_library()


def test_adxl345_rig_reads_the_simulated_csv(library: Path,
                                             simulated: tuple[Path, Path]) -> None:
    csv, rig_path = simulated
    rig = load_rig(rig_path)
    data = read_accel_csv(csv, rig)
    with VirtualBus(library) as vb:
        devices = vb.attach_rig(rig)
        assert list(devices) == ["a.0", "a.1", "b.0", "b.1"]
        assert vb.load_motion_csv(csv) == 4
        bus = SimSMBus(vb)
        channels = [s.mux_channel for link in ("a", "b") for s in rig.links[link].sensors]
        address = rig.links["a"].sensors[0].address
        for ch in channels:
            bus.write_byte(MUX, 1 << ch)
            assert bus.read_byte(MUX) == 1 << ch
            assert bus.read_byte_data(address, 0x00) == 0xE5  # DEVID
            bus.write_byte_data(address, 0x31, 0x08)  # full resolution, ±2 g
            bus.write_byte_data(address, 0x2C, 0x0A)  # 100 Hz, the CSV's rate
            bus.write_byte_data(address, 0x2D, 0x08)  # measure
            assert bus.read_i2c_block_data(address, 0x2C, 2) == [0x0A, 0x08]
        for k in range(1, len(data.t)):
            vb.set_time_us(k * 10_000 + 4_000)  # between rows: the conversion at row k
            for i, ch in enumerate(channels):
                bus.write_byte(MUX, 1 << ch)
                w, r = i2c_msg.write(address, [0x30]), i2c_msg.read(address, 8)
                bus.i2c_rdwr(w, r)
                raw = bytes(r)
                assert raw[0] & 0x80, f"no DATA_READY at row {k}, sensor {i}"
                counts = np.array([_le16(raw, 2), _le16(raw, 4), _le16(raw, 6)])
                np.testing.assert_allclose(counts * ADXL345_LSB, data.readings[k, i],
                                           atol=ADXL345_LSB * 1.0001)
        for dev in devices.values():
            c = vb.device_counters(dev)
            assert c.samples == len(data.t) - 1
            assert c.overruns == 0 and c.samples_read == c.samples


def test_mux_gates_channels_and_nacks_raise_eremoteio(library: Path) -> None:
    with VirtualBus(library) as vb:
        assert vb.attach_spec("a.0 adxl345 0x53 2\nb.0 adxl345 0x53 5\n") == 2
        bus = SimSMBus(vb)
        with pytest.raises(OSError) as exc:
            bus.read_byte_data(0x53, 0)  # power-up: every channel off
        assert exc.value.errno == errno.EREMOTEIO
        bus.write_byte(MUX, 0x04)
        assert bus.read_byte_data(0x53, 0) == 0xE5
        bus.write_byte_data(0x53, 0x1E, 0x7F)  # OFSX of a.0 only
        bus.write_byte(MUX, 0x20)
        assert bus.read_byte_data(0x53, 0x1E) == 0x00
        assert vb.device_info(vb.find_device("b.0")) == (Model.ADXL345, 0x53, 0, 5)
        assert vb.bus_counters().address_nacks == 1


def test_adxl357_and_bno055_configure_and_read(library: Path) -> None:
    with VirtualBus(library) as vb:
        mux = vb.add_mux(MUX)
        acc = vb.add_device(Model.ADXL357, 0x1D, mux, 0, "a.0")
        bno = vb.add_device("bno055", 0x28, mux, 1, "a.1")
        t = np.array([0.0, 1.0])
        vb.set_motion("a.0", t, np.array([[1.5 * G, -0.3 * G, 0.0], [1.5 * G, -0.3 * G, 0.0]]))
        vb.set_constant_motion(bno, [1.23, -4.56, 9.81])
        bus = SimSMBus(vb)
        bus.write_byte(MUX, 0x01)
        assert bus.read_i2c_block_data(0x1D, 0x00, 3) == [0xAD, 0x1D, 0xED]
        bus.write_byte_data(0x1D, 0x28, 0x02)  # ODR 1000 Hz (in standby)
        bus.write_byte_data(0x1D, 0x2D, 0x00)  # measure
        bus.write_byte(MUX, 0x02)
        assert bus.read_byte_data(0x28, 0x00) == 0xA0
        bus.write_byte_data(0x28, 0x3B, 0x00)  # m/s²
        bus.write_byte_data(0x28, 0x3D, 0x01)  # ACCONLY: 7 ms to switch
        vb.advance_us(10_000)
        d = bytes(bus.read_i2c_block_data(0x28, 0x08, 6))
        assert [_le16(d, 0), _le16(d, 2), _le16(d, 4)] == [123, -456, 981]
        bus.write_byte(MUX, 0x01)
        raw = bus.read_i2c_block_data(0x1D, 0x04, 13)
        assert raw[0] & 1  # DATA_RDY
        x = (raw[4] << 12) | (raw[5] << 4) | (raw[6] >> 4)
        assert x == 76800  # 1.5 g at 51200 LSB/g, 20-bit left-justified big-endian
        assert vb.device_counters(acc).config_violations == 0


def test_faults(library: Path) -> None:
    with VirtualBus(library) as vb:
        vb.attach_spec("a.0 adxl345 0x53 -1\n")
        dev = vb.find_device("a.0")
        vb.set_constant_motion(dev, [0.5 * G, -0.25 * G, G])
        bus = SimSMBus(vb)
        vb.inject_fault(dev, Fault.WRONG_ID)
        assert bus.read_byte_data(0x53, 0) == 0x1A
        vb.inject_fault(dev, Fault.NACK)
        with pytest.raises(I2cNackError) as exc:
            bus.read_byte_data(0x53, 0)
        assert exc.value.result == I2cResult.ADDRESS_NACK
        vb.clear_fault(dev)
        assert bus.read_byte_data(0x53, 0) == 0xE5
        bus.write_byte_data(0x53, 0x31, 0x08)
        bus.write_byte_data(0x53, 0x2D, 0x08)
        vb.inject_fault(dev, Fault.SATURATE)
        vb.advance_us(20_000)
        d = bytes(bus.read_i2c_block_data(0x53, 0x32, 6))
        assert [_le16(d, 0), _le16(d, 2), _le16(d, 4)] == [511, -512, 511]
        vb.clear_fault(dev, Fault.SATURATE)
        vb.inject_fault(dev, Fault.FROZEN, 1)
        vb.advance_us(20_000)
        assert not bus.read_byte_data(0x53, 0x30) & 0x80
        with pytest.raises(InputError, match="not modelled"):
            vb.inject_fault(vb.add_mux(0x71), Fault.SATURATE)


def test_bus_time_at_400khz(library: Path) -> None:
    with VirtualBus(library, scl_hz=400_000) as vb:
        vb.attach_spec("a.0 adxl345 0x53 -1\n")
        t0 = vb.time_ns
        assert len(vb.write_read(0x53, [0x32], 6)) == 6
        # S + SLA+W + reg + Sr + SLA+R + 6 bytes + P = 84 SCL periods = 210 µs (docs/sensors.md §B)
        assert vb.time_ns - t0 == 210_000
        c = vb.bus_counters()
        assert isinstance(c, BusCounters) and c.scl_bits == 84
        assert c.bus_time_s() == pytest.approx(210e-6)


def test_malformed_csv_names_line_and_field(library: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("t,a.0.x,a.0.y,a.0.z\n0,1,2,3\n0.01,1,oops,3\n")
    with VirtualBus(library) as vb, pytest.raises(InputError, match=r"line 3, field 'a\.0\.y'"):
        vb.load_motion_csv(bad)


def test_rig_spec_matches_the_csv_labels(example_rig_path: Path) -> None:
    spec = rig_spec(load_rig(example_rig_path))
    assert spec.splitlines() == ["mux 0x70", "a.0 adxl345 0x53 0", "a.1 adxl345 0x1d 0",
                                 "b.0 adxl345 0x53 1", "b.1 adxl357 0x1d 1"]


def test_bno055_gyro_rig_reads_accel_and_gyro_columns(library: Path, tmp_path: Path) -> None:
    csv, rig_path = tmp_path / "g.csv", tmp_path / "g.toml"
    assert main(["simulate", "--scenario", "gravity-fast-periodic", "--gyros", "--seconds", "1",
                 "--out", str(csv), "--rig-out", str(rig_path)]) == 0
    rig = load_rig(rig_path)
    data = read_accel_csv(csv, rig)
    assert data.gyro is not None
    sensors = [s for link in ("a", "b") for s in rig.links[link].sensors]
    assert {s.model for s in sensors} == {"bno055"}
    with VirtualBus(library) as vb:
        vb.attach_rig(rig)
        assert vb.load_motion_csv(csv) == 4
        bus = SimSMBus(vb)
        for s in sensors:
            bus.write_byte(MUX, 1 << s.mux_channel)
            bus.write_byte_data(s.address, 0x07, 1)  # page 1
            bus.write_byte_data(s.address, 0x08, 0x0D)  # ACC_Config: 4 g, 62.5 Hz -> 125 Hz
            bus.write_byte_data(s.address, 0x0A, 0x28)  # GYR_Config_0: 2000 dps, ODR 100 Hz
            bus.write_byte_data(s.address, 0x07, 0)
            bus.write_byte_data(s.address, 0x3B, 0x02)  # accel m/s², gyro rad/s (900 LSB)
            bus.write_byte_data(s.address, 0x3D, 0x07)  # AMG
        for k in range(4, len(data.t), 4):  # 40 ms: both grids (8 ms, 10 ms) meet a CSV row
            vb.set_time_us(k * 10_000 + 1)
            for i, s in enumerate(sensors):
                bus.write_byte(MUX, 1 << s.mux_channel)
                acc = bytes(bus.read_i2c_block_data(s.address, 0x08, 6))
                gyr = bytes(bus.read_i2c_block_data(s.address, 0x14, 6))
                a = np.array([_le16(acc, j) for j in (0, 2, 4)]) * 0.01
                g = np.array([_le16(gyr, j) for j in (0, 2, 4)]) / 900.0
                np.testing.assert_allclose(a, data.readings[k, i], atol=0.01 * 1.0001)
                np.testing.assert_allclose(g, data.gyro[k, i], atol=1.0001 / 900.0)


def test_import_loads_nothing() -> None:
    # Importing neither finds nor maps the library (a bad override would raise if it tried).
    code = ("import os; os.environ['JOINTANGLE_SIMDEV_LIB'] = '/nonexistent';"
            "import jointangle.boards.sim_devices;"
            "maps = open('/proc/self/maps').read();"
            "assert 'libja_sim_devices' not in maps; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "ok"
