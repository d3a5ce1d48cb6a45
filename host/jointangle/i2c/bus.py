"""Opening the bus `--i2c BUS` names: a Linux I2C adapter (/dev/i2c-N via smbus2) or the fake.

- `N` (a number): ``smbus2.SMBus(N)`` on /dev/i2c-N (Raspberry Pi: 1), at whatever clock the
  adapter is set to (400 kHz: ``dtparam=i2c_arm_baudrate=400000``). The BNO055 stretches the
  clock (docs/sensors.md §A3): an adapter that mishandles clock stretching shows it as NACKs or
  garbage from that part only.
- `sim`: the virtual TCA9548A + sensors (simdev.VirtualBus) attached from the rig, playing a
  scenario's motion in a loop, through `simdev.SimSMBus` in real time at 400 kHz: every
  transaction costs its SCL periods in wall-clock time, as on a real bus.
"""

from __future__ import annotations

import errno
from dataclasses import dataclass
from typing import Any

from jointangle.boards.sim_devices import SimSMBus, VirtualBus
from jointangle.errors import InputError
from jointangle.i2c.devices import SMBusLike
from jointangle.rig import Rig
from jointangle.sim.scenarios import simulate

SIM_SCL_HZ = 400_000
FIELD = "--i2c"


@dataclass
class OpenBus:
    bus: SMBusLike
    what: str
    virtual: Any = None  # the simdev.VirtualBus behind a fake bus (faults, counters)

    def close(self) -> None:
        self.bus.close()
        if self.virtual is not None:
            self.virtual.close()


def sim_bus(rig: Rig, scenario: str = "gravity-slow-periodic", seed: int = 0,
            seconds: float = 20.0, realtime: bool = True) -> OpenBus:
    """The fake bus with the rig's parts on it, fed with `scenario` (looped)."""
    vb = VirtualBus(scl_hz=SIM_SCL_HZ)
    ids = vb.attach_rig(rig)
    sim = simulate(scenario, seed=seed, rate_hz=rig.sample_rate_hz, seconds=seconds, rig=rig)
    for k, name in enumerate(ids):
        vb.set_motion(name, sim.t, sim.readings[:, k, :])
    vb.set_motion_loop(True)
    return OpenBus(SimSMBus(vb, realtime=realtime),
                   f"virtual bus at {SIM_SCL_HZ // 1000} kHz ({scenario})", vb)


def open_bus(spec: str, rig: Rig, scenario: str = "gravity-slow-periodic",
             seed: int = 0) -> OpenBus:
    if spec == "sim":
        return sim_bus(rig, scenario, seed)
    if not spec.isdigit():
        raise InputError(f"{spec!r}: expected a bus number (1 for /dev/i2c-1) or 'sim'",
                         field=FIELD)

    path = f"/dev/i2c-{spec}"
    try:
        from smbus2 import SMBus  # Linux's i2c-dev (smbus2 needs fcntl: not on Windows)

        bus = SMBus(int(spec))
    except ImportError:
        raise InputError(f"{path}: a bus number needs Linux's i2c-dev (smbus2), which this "
                         "system lacks", field=FIELD) from None
    except FileNotFoundError:
        raise InputError(f"{path} does not exist: enable I2C (Raspberry Pi: raspi-config → "
                         "Interface Options → I2C) or `modprobe i2c-dev`", field=FIELD) from None
    except PermissionError:
        raise InputError(f"{path}: permission denied (add yourself to the i2c group)",
                         field=FIELD) from None
    except OSError as exc:
        if exc.errno == errno.ENODEV:
            raise InputError(f"{path}: no such adapter", field=FIELD) from None
        raise InputError(f"{path}: {exc.strerror or exc}", field=FIELD) from None
    return OpenBus(bus, path)
