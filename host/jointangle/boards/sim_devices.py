"""The virtual I2C devices (firmware/sim/devices) from Python, through their C ABI.

The same register-level models of the TCA9548A, ADXL345, ADXL357 and BNO055 that serve the
native and AVR virtual boards, loaded with ctypes from ``libja_sim_devices.so``
(firmware/sim/devices/ja_sim_devices.h). Two layers:

- `VirtualBus`: build a bus (explicitly or from a rig), feed it motion (an accelerations CSV from
  ``jointangle simulate``, arrays, or a constant pose), move device time, run transactions at
  byte or transaction level, inject faults and read counters.
- `SimSMBus`: the subset of smbus2's ``SMBus`` the host's I2C driver uses (byte and block
  register access, ``i2c_rdwr``) over a `VirtualBus`; a NACK raises ``OSError(EREMOTEIO)`` as
  Linux i2c-dev does. Bus time at 400 kHz is charged when the bus is created with ``scl_hz``.

Importing this module has no side effects; the library is found (like the firmware replay
library) through ``$JOINTANGLE_SIMDEV_LIB`` or the repository's ``build/`` tree.
"""

from __future__ import annotations

import ctypes
import errno
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

import numpy as np

from jointangle.built import find_built
from jointangle.errors import InputError
from jointangle.rig import Rig

LIBRARY_ENV = "JOINTANGLE_SIMDEV_LIB"
LIBRARY_NAME = "libja_sim_devices.so"
ABI_VERSION = 2  # ja_sim_devices.h JA_SIM_ABI_VERSION
I2C_M_RD = 0x0001  # linux/i2c.h: read message
DEFAULT_MUX_ADDRESS = 0x70


class Model(IntEnum):
    ADXL345 = 1
    ADXL357 = 2
    BNO055 = 3
    TCA9548A = 4


class Fault(IntEnum):
    """Injectable faults; parameters as firmware/sim/devices/i2c_target.hpp `FaultKind`."""

    NACK = 1  # param 0: refuse the address; 1: NACK written bytes; N ≥ 2: one address in N
    WRONG_ID = 2  # ID registers read param (0: complement); mux: read-back XOR param (0: 0xFF)
    SATURATE = 3  # outputs at the rail with the input's sign; param = axis mask (0: all)
    FROZEN = 4  # param 0: values stuck, data-ready continues; 1: conversions stop


class I2cResult(IntEnum):
    OK = 0
    ADDRESS_NACK = 1
    DATA_NACK = 2
    BUS_ERROR = 3


class I2cMsg(Protocol):
    """What `SimSMBus.i2c_rdwr` needs of a message (smbus2's ``i2c_msg`` has it)."""

    addr: int
    flags: int
    len: int
    buf: Any


_DEVICE_COUNTERS = ("transactions", "address_nacks", "bytes_written", "bytes_read", "samples",
                    "samples_read", "overruns", "writes_ignored", "config_violations")
_BUS_COUNTERS = ("starts", "repeated_starts", "stops", "address_acks", "address_nacks",
                 "data_nacks", "bytes_written", "bytes_read", "bus_errors", "scl_bits")


class _DeviceCountersC(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint64) for n in _DEVICE_COUNTERS]


class _BusCountersC(ctypes.Structure):
    _fields_ = [(n, ctypes.c_uint64) for n in _BUS_COUNTERS]


@dataclass(frozen=True)
class DeviceCounters:
    """What one virtual device saw and did (monotonic)."""

    transactions: int
    address_nacks: int
    bytes_written: int
    bytes_read: int
    samples: int
    samples_read: int
    overruns: int
    writes_ignored: int
    config_violations: int


@dataclass(frozen=True)
class BusCounters:
    """Bus-wide counts; ``scl_bits`` gives the bus time at any clock rate."""

    starts: int
    repeated_starts: int
    stops: int
    address_acks: int
    address_nacks: int
    data_nacks: int
    bytes_written: int
    bytes_read: int
    bus_errors: int
    scl_bits: int

    def bus_time_s(self, scl_hz: float = 400_000.0) -> float:
        """Time the bus was busy at `scl_hz` (9 periods per byte, 1 per START/Sr/STOP)."""
        return self.scl_bits / scl_hz


class I2cNackError(OSError):
    """A transaction was not acknowledged (errno EREMOTEIO, as Linux i2c-dev reports it)."""

    def __init__(self, addr: int, result: I2cResult) -> None:
        super().__init__(errno.EREMOTEIO, f"I2C 0x{addr:02x}: {result.name.lower()}")
        self.addr = addr
        self.result = result


def find_library() -> Path:
    """The device library: $JOINTANGLE_SIMDEV_LIB, else the repository's build tree."""
    return find_built(LIBRARY_NAME, "firmware/sim", env=LIBRARY_ENV, target="ja_sim_devices",
                      what="virtual device library", field=LIBRARY_ENV)


def rig_spec(rig: Rig) -> str:
    """The rig as the C ABI's attach text: one "<id> <model> <address> <channel>" per sensor,
    ids as the accelerations CSV names them (a.0, a.1, …, b.0, …)."""
    lines = [f"mux 0x{DEFAULT_MUX_ADDRESS:02x}"]
    for link in ("a", "b"):
        for i, s in enumerate(rig.links[link].sensors):
            lines.append(f"{link}.{i} {s.model} 0x{s.address:02x} {s.mux_channel}")
    return "\n".join(lines) + "\n"


_U8P = ctypes.POINTER(ctypes.c_uint8)
_DP = ctypes.POINTER(ctypes.c_double)


def _load(path: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(path))
    sigs: dict[str, tuple[Any, list[Any]]] = {
        "ja_sim_abi_version": (ctypes.c_uint32, []),
        "ja_sim_create": (ctypes.c_void_p, []),
        "ja_sim_destroy": (None, [ctypes.c_void_p]),
        "ja_sim_last_error": (ctypes.c_char_p, [ctypes.c_void_p]),
        "ja_sim_add_mux": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint8, ctypes.c_int,
                                          ctypes.c_int]),
        "ja_sim_add_device": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint8,
                                             ctypes.c_int, ctypes.c_int, ctypes.c_char_p]),
        "ja_sim_attach_rig": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p]),
        "ja_sim_device_count": (ctypes.c_int, [ctypes.c_void_p]),
        "ja_sim_device_info": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int] +
                               [ctypes.POINTER(ctypes.c_int)] * 4),
        "ja_sim_find_device": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p]),
        "ja_sim_set_clock": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int, ctypes.c_double,
                                            ctypes.c_double]),
        "ja_sim_load_motion_csv": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p]),
        "ja_sim_set_motion": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t,
                                             _DP, _DP, _DP]),
        "ja_sim_set_constant_motion": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int, _DP, _DP]),
        "ja_sim_set_motion_loop": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int]),
        "ja_sim_set_time_ns": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint64]),
        "ja_sim_time_ns": (ctypes.c_uint64, [ctypes.c_void_p]),
        "ja_sim_set_scl_hz": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint32]),
        "ja_sim_bus_start": (ctypes.c_int, [ctypes.c_void_p]),
        "ja_sim_bus_write_byte": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint8]),
        "ja_sim_bus_read_byte": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int]),
        "ja_sim_bus_stop": (ctypes.c_int, [ctypes.c_void_p]),
        "ja_sim_i2c_write_read": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_uint8, _U8P,
                                                 ctypes.c_size_t, _U8P, ctypes.c_size_t]),
        "ja_sim_inject_fault": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int, ctypes.c_int,
                                               ctypes.c_uint32]),
        "ja_sim_clear_fault": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int, ctypes.c_int]),
        "ja_sim_power_cycle": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int]),
        "ja_sim_get_device_counters": (ctypes.c_int, [ctypes.c_void_p, ctypes.c_int,
                                                      ctypes.POINTER(_DeviceCountersC),
                                                      ctypes.c_size_t]),
        "ja_sim_get_bus_counters": (ctypes.c_int, [ctypes.c_void_p,
                                                   ctypes.POINTER(_BusCountersC),
                                                   ctypes.c_size_t]),
    }
    for name, (res, args) in sigs.items():
        fn = getattr(lib, name)
        fn.restype = res
        fn.argtypes = args
    version = lib.ja_sim_abi_version()
    if version != ABI_VERSION:
        raise InputError(f"{path}: device library ABI {version}, this host expects "
                         f"{ABI_VERSION}: rebuild it", field=LIBRARY_ENV)
    return lib


def _bytes_in(data: Iterable[int]) -> ctypes.Array[ctypes.c_uint8]:
    b = bytes(data)
    return (ctypes.c_uint8 * max(len(b), 1))(*b)


class VirtualBus:
    """One virtual I2C bus with its devices (see the module docstring)."""

    def __init__(self, library: Path | None = None, scl_hz: int = 0) -> None:
        self._lib = _load(library or find_library())
        self._h: int | None = self._lib.ja_sim_create()
        if not self._h:
            raise MemoryError("ja_sim_create failed")
        if scl_hz:
            self.set_scl_hz(scl_hz)

    # ---- life cycle ----
    def close(self) -> None:
        h = getattr(self, "_h", None)
        if h:
            self._lib.ja_sim_destroy(h)
            self._h = None

    def __enter__(self) -> VirtualBus:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def __del__(self) -> None:
        self.close()

    @property
    def _handle(self) -> int:
        if not self._h:
            raise ValueError("the virtual bus is closed")
        return self._h

    def _check(self, rc: int, what: str) -> int:
        if rc < 0:
            why = self._lib.ja_sim_last_error(self._handle).decode()
            raise InputError(f"{what}: {why or 'invalid argument'}", field=what)
        return rc

    # ---- building ----
    def add_mux(self, address: int = DEFAULT_MUX_ADDRESS, mux: int = -1, channel: int = 0) -> int:
        return self._check(self._lib.ja_sim_add_mux(self._handle, address, mux, channel),
                           "add_mux")

    def add_device(self, model: Model | str, address: int, mux: int = -1, channel: int = 0,
                   motion_id: str = "") -> int:
        m = Model[model.upper()] if isinstance(model, str) else model
        return self._check(self._lib.ja_sim_add_device(self._handle, int(m), address, mux,
                                                       channel, motion_id.encode()),
                           "add_device")

    def attach_spec(self, spec: str) -> int:
        """Attach devices from the C ABI's rig text; returns the number of sensors."""
        return self._check(self._lib.ja_sim_attach_rig(self._handle, spec.encode()), "rig")

    def attach_rig(self, rig: Rig) -> dict[str, int]:
        """Attach a rig's sensors (behind one TCA9548A at 0x70); {"a.0": device, …}."""
        self.attach_spec(rig_spec(rig))
        ids = [f"{link}.{i}" for link in ("a", "b") for i in range(len(rig.links[link].sensors))]
        return {i: self.find_device(i) for i in ids}

    def find_device(self, motion_id: str) -> int:
        return self._check(self._lib.ja_sim_find_device(self._handle, motion_id.encode()),
                           f"device {motion_id!r}")

    def set_clock(self, dev: int, ppm: float, phase: float) -> None:
        """The part's own conversion clock: oscillator error (ppm, + = fast) and grid phase
        (0 <= phase < 1 of a period); see ja_sim_set_clock in ja_sim_devices.h."""
        self._check(self._lib.ja_sim_set_clock(self._handle, dev, ppm, phase), "set_clock")

    @property
    def device_count(self) -> int:
        return int(self._lib.ja_sim_device_count(self._handle))

    def device_info(self, dev: int) -> tuple[Model, int, int, int]:
        """(model, address, mux device or -1, channel or -1)."""
        out = [ctypes.c_int() for _ in range(4)]
        self._check(self._lib.ja_sim_device_info(self._handle, dev, *map(ctypes.byref, out)),
                    "device_info")
        return Model(out[0].value), out[1].value, out[2].value, out[3].value

    # ---- motion ----
    def load_motion_csv(self, path: str | Path) -> int:
        """Bind every device to its columns of an accelerations CSV; returns how many."""
        return self._check(self._lib.ja_sim_load_motion_csv(self._handle, str(path).encode()),
                           str(path))

    def set_motion(self, motion_id: str, t_s: Sequence[float] | np.ndarray,
                   accel_mps2: np.ndarray, gyro_rps: np.ndarray | None = None) -> None:
        t = np.ascontiguousarray(t_s, dtype=np.float64)
        a = np.ascontiguousarray(accel_mps2, dtype=np.float64).reshape(-1, 3)
        g = None if gyro_rps is None else np.ascontiguousarray(gyro_rps,
                                                               dtype=np.float64).reshape(-1, 3)
        if a.shape[0] != t.shape[0] or (g is not None and g.shape[0] != t.shape[0]):
            raise InputError("motion arrays disagree in length", field=motion_id)
        self._check(self._lib.ja_sim_set_motion(
            self._handle, motion_id.encode(), t.shape[0], t.ctypes.data_as(_DP),
            a.ctypes.data_as(_DP), None if g is None else g.ctypes.data_as(_DP)), motion_id)

    def set_constant_motion(self, dev: int, accel_mps2: Sequence[float],
                            gyro_rps: Sequence[float] | None = None) -> None:
        a = (ctypes.c_double * 3)(*accel_mps2)
        g = None if gyro_rps is None else (ctypes.c_double * 3)(*gyro_rps)
        self._check(self._lib.ja_sim_set_constant_motion(
            self._handle, dev, ctypes.cast(a, _DP), None if g is None else ctypes.cast(g, _DP)),
            "set_constant_motion")

    def set_motion_loop(self, loop: bool) -> None:
        self._lib.ja_sim_set_motion_loop(self._handle, int(loop))

    # ---- time ----
    @property
    def time_ns(self) -> int:
        return int(self._lib.ja_sim_time_ns(self._handle))

    def set_time_us(self, t_us: float) -> None:
        """Move device time forward (earlier times are ignored: time never runs back)."""
        self._lib.ja_sim_set_time_ns(self._handle, round(t_us * 1000.0))

    def advance_us(self, dt_us: float) -> None:
        self._lib.ja_sim_set_time_ns(self._handle, self.time_ns + round(dt_us * 1000.0))

    def set_scl_hz(self, hz: int) -> None:
        """Charge every SCL period at `hz` to device time (0: transfers take no time)."""
        self._lib.ja_sim_set_scl_hz(self._handle, hz)

    # ---- byte level ----
    def start(self) -> None:
        self._lib.ja_sim_bus_start(self._handle)

    def write_byte(self, byte: int) -> bool:
        """Address or data byte; True if acknowledged."""
        return bool(self._lib.ja_sim_bus_write_byte(self._handle, byte))

    def read_byte(self, ack: bool) -> int:
        return int(self._lib.ja_sim_bus_read_byte(self._handle, int(ack)))

    def stop(self) -> None:
        self._lib.ja_sim_bus_stop(self._handle)

    # ---- transactions ----
    def transact(self, addr: int, write: Iterable[int] = b"",
                 read: int = 0) -> tuple[I2cResult, bytes]:
        """Write, (repeated START) read, STOP; returns the result and the bytes read. read = 0
        is a plain write; no bytes either way probes the address."""
        w = bytes(write)
        wbuf = _bytes_in(w)
        rbuf = (ctypes.c_uint8 * max(read, 1))()
        rc = self._check(self._lib.ja_sim_i2c_write_read(self._handle, addr, wbuf, len(w), rbuf,
                                                         read), "transaction")
        return I2cResult(rc), bytes(rbuf[:read])

    def write(self, addr: int, data: Iterable[int]) -> None:
        res, _ = self.transact(addr, data, 0)
        if res != I2cResult.OK:
            raise I2cNackError(addr, res)

    def read(self, addr: int, n: int) -> bytes:
        res, data = self.transact(addr, b"", n)
        if res != I2cResult.OK:
            raise I2cNackError(addr, res)
        return data

    def write_read(self, addr: int, data: Iterable[int], n: int) -> bytes:
        res, out = self.transact(addr, data, n)
        if res != I2cResult.OK:
            raise I2cNackError(addr, res)
        return out

    # ---- faults ----
    def inject_fault(self, dev: int, fault: Fault, param: int = 0) -> None:
        self._check(self._lib.ja_sim_inject_fault(self._handle, dev, int(fault), param),
                    "inject_fault")

    def clear_fault(self, dev: int, fault: Fault | None = None) -> None:
        self._check(self._lib.ja_sim_clear_fault(self._handle, dev,
                                                 0 if fault is None else int(fault)),
                    "clear_fault")

    def power_cycle(self, dev: int) -> None:
        self._check(self._lib.ja_sim_power_cycle(self._handle, dev), "power_cycle")

    # ---- counters ----
    def device_counters(self, dev: int) -> DeviceCounters:
        c = _DeviceCountersC()
        self._check(self._lib.ja_sim_get_device_counters(self._handle, dev, ctypes.byref(c),
                                                         ctypes.sizeof(c)), "device_counters")
        return DeviceCounters(*(int(getattr(c, n)) for n in _DEVICE_COUNTERS))

    def bus_counters(self) -> BusCounters:
        c = _BusCountersC()
        self._check(self._lib.ja_sim_get_bus_counters(self._handle, ctypes.byref(c),
                                                      ctypes.sizeof(c)), "bus_counters")
        return BusCounters(*(int(getattr(c, n)) for n in _BUS_COUNTERS))


class SimSMBus:
    """smbus2.SMBus-like access to a `VirtualBus` (the methods the host's I2C driver uses).

    With ``realtime``, the fake bus behaves like a real one in time: device time follows the
    wall clock, every transaction costs its own SCL periods (the VirtualBus needs ``scl_hz``,
    e.g. 400 kHz) and the caller is held back by that long, as by a blocking i2c-dev ioctl:
    the bus time owed is added up and slept off once it exceeds `SLEEP_QUANTUM_NS` (the
    process sleeps, as in the kernel's wait for the adapter's interrupt, instead of spinning;
    oversleeping is credited to the next transactions). Over many transactions the caller's
    wall time is its own CPU time plus the bus time.
    """

    SLEEP_QUANTUM_NS = 1_000_000

    def __init__(self, bus: VirtualBus, realtime: bool = False) -> None:
        self.bus = bus
        self.realtime = realtime
        self._t0_ns = time.perf_counter_ns() - bus.time_ns
        self._owed_ns = 0  # bus time not yet slept off (negative: slept too long)
        self._dev_ns = 0

    def _begin(self) -> None:
        if self.realtime:
            now = time.perf_counter_ns() - self._t0_ns
            self.bus.set_time_us((now + max(self._owed_ns, 0)) / 1000.0)
            self._dev_ns = self.bus.time_ns

    def _end(self) -> None:
        if self.realtime:
            self._owed_ns += self.bus.time_ns - self._dev_ns
            if self._owed_ns > self.SLEEP_QUANTUM_NS:
                t = time.perf_counter_ns()
                time.sleep(self._owed_ns * 1e-9)
                self._owed_ns -= time.perf_counter_ns() - t
                self._owed_ns = max(self._owed_ns, -self.SLEEP_QUANTUM_NS)

    def close(self) -> None:
        """Nothing to release (the VirtualBus is the caller's)."""

    def __enter__(self) -> SimSMBus:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def _write(self, addr: int, data: Sequence[int]) -> None:
        self._begin()
        try:
            self.bus.write(addr, data)
        finally:
            self._end()

    def _write_read(self, addr: int, data: Sequence[int], n: int) -> bytes:
        self._begin()
        try:
            return self.bus.write_read(addr, data, n) if data else self.bus.read(addr, n)
        finally:
            self._end()

    def read_byte(self, i2c_addr: int, force: bool | None = None) -> int:
        return self._write_read(i2c_addr, [], 1)[0]

    def write_byte(self, i2c_addr: int, value: int, force: bool | None = None) -> None:
        self._write(i2c_addr, [value])

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        return self._write_read(i2c_addr, [register], 1)[0]

    def write_byte_data(self, i2c_addr: int, register: int, value: int,
                        force: bool | None = None) -> None:
        self._write(i2c_addr, [register, value])

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]:
        if not 0 < length <= 32:
            raise ValueError("SMBus block length must be 1..32")
        return list(self._write_read(i2c_addr, [register], length))

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int],
                             force: bool | None = None) -> None:
        if len(data) > 32:
            raise ValueError("SMBus block length must be at most 32")
        self._write(i2c_addr, [register, *data])

    def i2c_rdwr(self, *msgs: I2cMsg) -> None:
        """Combined transaction: START, each message (repeated START between), one STOP;
        read messages are filled in place. Raises I2cNackError (EREMOTEIO) on a NACK."""
        self._begin()
        try:
            self._rdwr(msgs)
        finally:
            self._end()

    def _rdwr(self, msgs: Sequence[I2cMsg]) -> None:
        b = self.bus
        if (len(msgs) == 2 and not msgs[0].flags & I2C_M_RD and msgs[1].flags & I2C_M_RD
                and msgs[0].addr == msgs[1].addr):
            # Write then read one address (register reads): one call into the library, the
            # same START, bytes, repeated START and STOP as the byte-level path below.
            res, data = b.transact(msgs[0].addr, ctypes.string_at(msgs[0].buf, msgs[0].len),
                                   msgs[1].len)
            if res != I2cResult.OK:
                raise I2cNackError(msgs[0].addr, res)
            ctypes.memmove(msgs[1].buf, data, msgs[1].len)
            return
        failure: tuple[int, I2cResult] | None = None
        for msg in msgs:
            b.start()
            read = bool(msg.flags & I2C_M_RD)
            if not b.write_byte((msg.addr << 1) | int(read)):
                failure = (msg.addr, I2cResult.ADDRESS_NACK)
                break
            if read:
                data = bytes(b.read_byte(i + 1 < msg.len) for i in range(msg.len))
                ctypes.memmove(msg.buf, data, msg.len)
            else:
                out = ctypes.string_at(msg.buf, msg.len)
                if not all(b.write_byte(x) for x in out):
                    failure = (msg.addr, I2cResult.DATA_NACK)
                    break
        b.stop()
        if failure:
            raise I2cNackError(*failure)
