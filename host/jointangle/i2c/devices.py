"""TCA9548A, ADXL345, ADXL357 and BNO055 on a Linux I2C bus through smbus2 (docs/sensors.md §A).

The same register sequences as the firmware's drivers (firmware/drivers), written for a bus
object with smbus2's ``SMBus`` interface (a real ``smbus2.SMBus(N)`` on /dev/i2c-N, or
``simdev.SimSMBus`` over the virtual devices). Every register read is ONE combined transaction
(``i2c_rdwr``: write the register pointer, repeated START, read n bytes, STOP) — the parts do
not keep the pointer across a STOP-START reliably, and it saves a START/STOP per read.

Errors: a NACK comes back from i2c-dev as OSError (EREMOTEIO, or EIO on some adapters); it is
turned into `I2cDeviceError` naming the part, its address and its mux channel.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Protocol

try:
    from smbus2 import i2c_msg
except ImportError:  # smbus2 needs fcntl, which Windows lacks; the command line still starts
    i2c_msg = None  # type: ignore[assignment,misc]

from jointangle.protocol import messages as msgs

MUX_ADDRESS = 0x70


class SMBusLike(Protocol):
    """What the drivers use of smbus2.SMBus."""

    def i2c_rdwr(self, *i2c_msgs: Any) -> None: ...

    def close(self) -> None: ...


class I2cDeviceError(RuntimeError):
    """A device did not answer, or answered wrongly. `status` is the protocol's SensorStatus
    bit it maps to (nack, wrong_id)."""

    def __init__(self, what: str, status: int) -> None:
        super().__init__(what)
        self.status = status


class MuxMismatchError(I2cDeviceError):
    """The TCA9548A's control register read back differs from what was written."""


def read_registers(bus: SMBusLike, addr: int, reg: int, n: int) -> bytes:
    """Combined write-read: [S addr+W reg Sr addr+R n bytes P]."""
    w = i2c_msg.write(addr, [reg])
    r = i2c_msg.read(addr, n)
    bus.i2c_rdwr(w, r)
    return bytes(r)


def write_register(bus: SMBusLike, addr: int, reg: int, value: int) -> None:
    bus.i2c_rdwr(i2c_msg.write(addr, [reg, value]))


class Tca9548a:
    """The multiplexer: selects one channel and verifies it by reading the control register
    back in the same transaction (write mask, Sr, read 1). The selection is cached; a failed
    select forgets it, so the next access selects (and verifies) again."""

    def __init__(self, bus: SMBusLike, addr: int = MUX_ADDRESS) -> None:
        self.bus = bus
        self.addr = addr
        self.selected: int | None = None
        self.mismatches = 0

    def select(self, channel: int) -> None:
        if channel == self.selected:
            return
        mask = 1 << channel
        self.selected = None
        w = i2c_msg.write(self.addr, [mask])
        r = i2c_msg.read(self.addr, 1)
        try:
            self.bus.i2c_rdwr(w, r)
        except OSError as exc:
            raise I2cDeviceError(f"mux 0x{self.addr:02x}: selecting channel {channel}: "
                                 f"{exc.strerror or exc} (no acknowledge)",
                                 msgs.SensorStatus.NACK) from None
        back = bytes(r)[0]
        if back != mask:
            self.mismatches += 1
            raise MuxMismatchError(f"mux 0x{self.addr:02x}: channel {channel} selected "
                                   f"(0x{mask:02x}) but the control register reads back "
                                   f"0x{back:02x}", msgs.SensorStatus.NACK)
        self.selected = channel


@dataclass(frozen=True)
class Part:
    model: str
    address: int
    mux_channel: int  # 255: on the bus directly
    range_g: int
    label: str  # "a.0", ...

    def where(self) -> str:
        via = "direct" if self.mux_channel == 255 else f"mux channel {self.mux_channel}"
        return f"sensor {self.label} ({self.model} at 0x{self.address:02x}, {via})"


def _odr_code_adxl345(rate_hz: float) -> int:
    """The slowest ODR ≥ 1.6 × the loop rate (firmware app/sensor.cpp): ODR = 3200/2^(15−c)."""
    code = 0x0A
    while code < 0x0F and 3200.0 / (1 << (15 - code)) < 1.6 * rate_hz:
        code += 1
    return code


def _odr_code_adxl357(rate_hz: float) -> int:
    """ODR = 4000/2^c: the slowest ≥ 1.6 × the loop rate (firmware app/sensor.cpp)."""
    code = 6
    while code > 0 and 4000.0 / (1 << code) < 1.6 * rate_hz:
        code -= 1
    return code


class Sensor:
    """One accelerometer (any of the three models): configure(), then read() → counts."""

    def __init__(self, bus: SMBusLike, mux: Tca9548a | None, part: Part) -> None:
        self.bus = bus
        self.mux = mux
        self.part = part
        self.last: tuple[int, int, int] = (0, 0, 0)
        self._bno_last: tuple[int, int, int] | None = None

    def _sel(self) -> None:
        if self.mux is not None and self.part.mux_channel != 255:
            self.mux.select(self.part.mux_channel)

    def _read(self, reg: int, n: int) -> bytes:
        self._sel()
        try:
            return read_registers(self.bus, self.part.address, reg, n)
        except OSError as exc:
            raise self._nack(exc) from None

    def _write(self, reg: int, value: int) -> None:
        self._sel()
        try:
            write_register(self.bus, self.part.address, reg, value)
        except OSError as exc:
            raise self._nack(exc) from None

    def _nack(self, exc: OSError) -> I2cDeviceError:
        if self.mux is not None:
            self.mux.selected = None  # a NACK behind the mux may mean it lost its selection
        return I2cDeviceError(f"{self.part.where()}: {exc.strerror or exc} (no acknowledge)",
                              msgs.SensorStatus.NACK)

    def _wrong(self, what: str) -> I2cDeviceError:
        return I2cDeviceError(f"{self.part.where()}: {what}", msgs.SensorStatus.WRONG_ID)

    def configure(self, rate_hz: float) -> None:
        """The firmware drivers' sequences (drivers/*.cpp), with their ID and read-back checks."""
        m = self.part.model
        if m == "adxl345":
            if (dev := self._read(0x00, 1)[0]) != 0xE5:
                raise self._wrong(f"DEVID reads 0x{dev:02x}, an ADXL345 has 0xE5")
            fmt = 0x08 | {2: 0, 4: 1, 8: 2, 16: 3}[self.part.range_g]  # FULL_RES | range
            for reg, val in ((0x2D, 0x00), (0x31, fmt), (0x2C, _odr_code_adxl345(rate_hz)),
                             (0x2F, 0x00), (0x2E, 0x80), (0x38, 0x00), (0x2D, 0x08)):
                self._write(reg, val)
            if (back := self._read(0x31, 1)[0]) != fmt:
                raise self._wrong(f"DATA_FORMAT reads back 0x{back:02x}, wrote 0x{fmt:02x}")
        elif m == "adxl357":
            ids = self._read(0x00, 3)
            if ids != bytes([0xAD, 0x1D, 0xED]):
                raise self._wrong(f"ID registers read {ids.hex()}, an ADXL357 has ad1ded")
            self._write(0x2D, 0x01)  # standby: range and ODR change only there
            rng = (self._read(0x2C, 1)[0] & ~0x03) | {10: 1, 20: 2, 40: 3}[self.part.range_g]
            flt = (self._read(0x28, 1)[0] & ~0x0F) | _odr_code_adxl357(rate_hz)
            self._write(0x2C, rng)
            self._write(0x28, flt)
            if self._read(0x2C, 1)[0] != rng or self._read(0x28, 1)[0] != flt:
                raise self._wrong("RANGE/FILTER read back differs from what was written")
            self._write(0x2D, 0x00)  # measure
        elif m == "bno055":
            self._write(0x07, 0)  # page 0
            if (cid := self._read(0x00, 1)[0]) != 0xA0:
                raise self._wrong(f"CHIP_ID reads 0x{cid:02x}, a BNO055 has 0xA0")
            self._write(0x3D, 0x00)  # CONFIG mode
            time.sleep(0.020)
            acc = {2: 0, 4: 1, 8: 2, 16: 3}[self.part.range_g] | (5 << 2)  # 250 Hz bandwidth
            self._write(0x07, 1)
            self._write(0x08, acc)
            back = self._read(0x08, 1)[0]
            self._write(0x07, 0)
            if back != acc:
                raise self._wrong(f"ACC_Config reads back 0x{back:02x}, wrote 0x{acc:02x}")
            self._write(0x3B, 0x00)  # m/s²
            self._write(0x3D, 0x01)  # ACCONLY
            time.sleep(0.008)
            self._bno_last = None
        else:
            raise ValueError(f"unknown model {m!r}")

    def read(self) -> tuple[tuple[int, int, int], bool]:
        """(counts x, y, z, fresh): one transaction per sample (firmware ReadSample)."""
        m = self.part.model
        if m == "adxl345":
            b = self._read(0x30, 8)  # INT_SOURCE, then DATAX0..DATAZ1 (LE int16)
            if not b[0] & 0x80:
                return self.last, False
            self.last = (int.from_bytes(b[2:4], "little", signed=True),
                         int.from_bytes(b[4:6], "little", signed=True),
                         int.from_bytes(b[6:8], "little", signed=True))
            return self.last, True
        if m == "adxl357":
            b = self._read(0x04, 13)  # STATUS, FIFO_ENTRIES, TEMP2, TEMP1, XDATA3..ZDATA1
            if not b[0] & 0x01:
                return self.last, False
            d = b[4:]
            # 20-bit two's complement, big-endian, left-justified: (D3<<12)|(D2<<4)|(D1>>4).
            vals = []
            for k in range(3):
                v = (d[3 * k] << 12) | (d[3 * k + 1] << 4) | (d[3 * k + 2] >> 4)
                vals.append(v - (1 << 20) if v & (1 << 19) else v)
            self.last = (vals[0], vals[1], vals[2])
            return self.last, True
        b = self._read(0x08, 6)  # BNO055 ACC_DATA (LE int16), no data-ready: repeat = stale
        s = (int.from_bytes(b[0:2], "little", signed=True),
             int.from_bytes(b[2:4], "little", signed=True),
             int.from_bytes(b[4:6], "little", signed=True))
        fresh = s != self._bno_last
        self._bno_last = s
        self.last = s
        return s, fresh
