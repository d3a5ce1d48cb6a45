"""What a rig file tells a board: the commands that give the firmware its geometry.

The board keeps the rig in its configuration (APP.md "Commands"; saved with save_eeprom): one
set_sensor per slot in rig order (link, part, multiplexer channel, address, range, position and
in-plane rotation, positions in µm and rotations in µrad), one set_joint per link (the hinge
point in that link's frame), and set_calibration for each sensor whose rig entry carries a
calibration (S, offset). Pure: `rig_commands` builds the messages, the caller sends them.
"""

from __future__ import annotations

import math

import numpy as np

from jointangle.protocol import messages as msgs
from jointangle.rig import Rig, SensorConfig

NOT_MULTIPLEXED = 255  # set_sensor.mux_channel: on the bus itself
LINKS = {"a": msgs.Link.A, "b": msgs.Link.B}
Q24 = 2**24  # set_calibration's S
SAVE_CONFIRM = 0x5AFE  # save_eeprom.confirm: the board writes its EEPROM only with this
SAVE_TIMEOUT_S = 5.0  # the AVR writes ~560 EEPROM bytes at 3.4 ms each (APP.md)
CALIBRATION_FIELDS = ("s00", "s01", "s02", "s10", "s11", "s12", "s20", "s21", "s22",
                      "ox", "oy", "oz")  # S row by row (Q24), then the offset (µm/s²)


def calibration_message(slot: int, S: np.ndarray, offset: np.ndarray) -> msgs.SetCalibration:
    """set_calibration with S rounded to Q24 and the offset to µm/s²."""
    vals = [round(float(x) * Q24) for x in np.asarray(S, dtype=float).reshape(9)]
    vals += [round(float(x) * 1e6) for x in np.asarray(offset, dtype=float)]
    if any(not -(2**31) <= v < 2**31 for v in vals):
        raise ValueError(f"slot {slot}: calibration out of the protocol's range")
    return msgs.SetCalibration(slot=slot, **dict(zip(CALIBRATION_FIELDS, vals, strict=True)))


def _micro(v: float) -> int:
    return round(v * 1e6)


def sensor_command(slot: int, count: int, link: str, s: SensorConfig) -> msgs.SetSensor:
    """set_sensor for slot `slot` of `count`: the sensor as the rig describes it."""
    return msgs.SetSensor(slot=slot, count=count, link=LINKS[link],
                          model=msgs.SensorModel[s.model.upper()],
                          mux_channel=NOT_MULTIPLEXED if s.mux_channel < 0 else s.mux_channel,
                          address=s.address, range_g=s.range_g, x=_micro(s.position[0]),
                          y=_micro(s.position[1]), rotation=_micro(math.radians(s.rotation_deg)))


def rig_commands(rig: Rig) -> list[msgs.SetSensor | msgs.SetJoint | msgs.SetCalibration]:
    """The rig's geometry (and the calibrations it carries) as board commands, in the order the
    board takes them: every sensor slot, then the joints, then the calibrations."""
    placed = [(name, s) for name, link in rig.links.items() for s in link.sensors]
    out: list[msgs.SetSensor | msgs.SetJoint | msgs.SetCalibration] = [
        sensor_command(slot, len(placed), name, s) for slot, (name, s) in enumerate(placed)]
    out += [msgs.SetJoint(link=LINKS[name], x=_micro(link.joint[0]), y=_micro(link.joint[1]))
            for name, link in rig.links.items()]
    for slot, (_, s) in enumerate(placed):
        if s.S is not None or s.offset is not None:
            S = np.eye(3) if s.S is None else np.asarray(s.S, dtype=float)
            offset = np.zeros(3) if s.offset is None else np.asarray(s.offset, dtype=float)
            out.append(calibration_message(slot, S, offset))
    return out
