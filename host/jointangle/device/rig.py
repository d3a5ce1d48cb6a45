"""The rig as the board's filter sees it, and which of its sensors the filter runs on.

With `set_filter.accel_sigma` = 0 (the default) the firmware's Q̂ is the datasheet density on
x/y at its own rate plus LSB²/12, whatever the rig file says for the simulator: `device_rig`
builds that rig (rate from hello, datasheet noise, positions in µm). The firmware filters the
first four usable sensors of each link (`filter_choice`) and runs with at least two per link
(`filter_runs`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable

from jointangle.device.describe import enum_name
from jointangle.errors import InputError
from jointangle.estimators.mirror import MAX_SENSORS_PER_LINK, MIN_SENSORS_PER_LINK
from jointangle.protocol import messages as msgs
from jointangle.rig import LinkConfig, Rig, SensorConfig

# The sensor status bits that make the firmware leave a sensor out of its filter.
FAULT_BITS = (msgs.SensorStatus.NACK | msgs.SensorStatus.WRONG_ID | msgs.SensorStatus.SATURATED
              | msgs.SensorStatus.FROZEN | msgs.SensorStatus.BAD_CALIBRATION)


def check_inventory(rig: Rig, hello: msgs.Hello) -> None:
    """The rig's sensors are the board's (count, and per slot link, model and range), else
    InputError naming the first that differs."""
    sensors = rig.all_sensors()
    if len(sensors) != len(hello.sensors):
        raise InputError(f"the rig has {len(sensors)} sensors, the device reports "
                         f"{len(hello.sensors)}", field="rig")
    for (link, i, s), h in zip(sensors, hello.sensors, strict=True):
        where = f"links.{link}.sensors[{i}]"
        dev_link = "a" if h.link == 0 else "b"
        dev_model = enum_name(msgs.SensorModel, h.model)
        if dev_link != link or dev_model != s.model or h.range_g != s.range_g:
            raise InputError(f"rig says {s.model} ±{s.range_g} g on link {link}, the device "
                             f"has {dev_model} ±{h.range_g} g on link {dev_link}", field=where)


def _um(v: float) -> float:
    return round(v * 1e6) / 1e6


def board_read_delays(rig: Rig, hello: msgs.Hello) -> Rig:
    """The rig with each sensor's `read_delay_s` the board's (hello's `read_delay_us`: when it
    reads the sensor after the first; the board knows its bus, a rig file does not)."""
    check_inventory(rig, hello)
    delays = iter(h.read_delay_us * 1e-6 for h in hello.sensors)
    links = {name: dataclasses.replace(rig.links[name], sensors=tuple(
        dataclasses.replace(s, read_delay_s=next(delays)) for s in rig.links[name].sensors))
        for name in ("a", "b")}
    return dataclasses.replace(rig, links=links)


def device_rig(rig: Rig, hello: msgs.Hello) -> Rig:
    """The rig as the firmware's filter sees it: its rate, positions in µm, datasheet noise on
    x/y with quantisation (what `set_filter.accel_sigma = 0` means), the board's read delays
    (`board_read_delays`)."""
    rig = board_read_delays(rig, hello)

    def sensor(s: SensorConfig) -> SensorConfig:
        return dataclasses.replace(s, position=(_um(s.position[0]), _um(s.position[1])),
                                   noise_density_ug=None, quantize=True)

    links = {name: LinkConfig(joint=(_um(lc.joint[0]), _um(lc.joint[1])),
                              sensors=tuple(sensor(s) for s in lc.sensors))
             for name, lc in rig.links.items()}
    rate = float(hello.sample_rate_hz) if hello.sample_rate_hz else rig.sample_rate_hz
    return dataclasses.replace(rig, links=links, sample_rate_hz=rate)


def filter_choice(rig: Rig, status: Iterable[int]) -> tuple[int, ...]:
    """Sensor indices (rig order) the firmware filters: the first four usable per link."""
    st = list(status)
    chosen: list[int] = []
    k = 0
    for name in ("a", "b"):
        n = rig.sensor_count(name)
        usable = [k + i for i in range(n) if not st[k + i] & FAULT_BITS][:MAX_SENSORS_PER_LINK]
        chosen += usable
        k += n
    return tuple(chosen)


def filter_runs(rig: Rig, chosen: tuple[int, ...]) -> bool:
    """Whether the firmware's filter runs on this choice: at least two usable sensors per link."""
    na = rig.sensor_count("a")
    in_a = sum(1 for i in chosen if i < na)
    return min(in_a, len(chosen) - in_a) >= MIN_SENSORS_PER_LINK


def sub_rig(rig: Rig, chosen: tuple[int, ...]) -> Rig:
    """The rig with only the chosen sensors (indices in rig order)."""
    links: dict[str, LinkConfig] = {}
    k = 0
    for name in ("a", "b"):
        lc = rig.links[name]
        keep = tuple(s for i, s in enumerate(lc.sensors) if k + i in chosen)
        links[name] = LinkConfig(joint=lc.joint, sensors=keep)
        k += len(lc.sensors)
    return dataclasses.replace(rig, links=links)
