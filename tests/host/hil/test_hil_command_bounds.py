"""HIL: every command value the board refuses (protocol/messages.toml says which are legal) is
answered with an ack carrying the reason, which the host prints, and changes nothing (issue 16
item 9). Runs against every virtual board (conftest.hil_port) through the protocol."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from jointangle.boards.options import LaunchOptions
from jointangle.protocol import messages as msgs
from jointangle.protocol.link import CommandError, Link
from jointangle.transport import open_port

ONE = 1 << 24  # 1.0 in set_calibration's Q24


def calibration(**entries: int) -> msgs.SetCalibration:
    fields = dict(slot=0, s00=ONE, s01=0, s02=0, s10=0, s11=ONE, s12=0, s20=0, s21=0, s22=ONE,
                  ox=0, oy=0, oz=0)
    fields.update(entries)
    return msgs.SetCalibration(**fields)


REFUSED = [
    ("S all zero (singular)", calibration(s00=0, s11=0, s22=0), "bad_calibration"),
    ("S entries at INT32_MAX", calibration(s00=2**31 - 1, s11=2**31 - 1), "bad_calibration"),
    ("two equal rows", calibration(s01=ONE, s10=ONE), "bad_calibration"),
    ("an offset of 60 m/s²", calibration(oz=60_000_000), "bad_calibration"),
    ("a slot outside the rig", calibration(slot=9), "bad_value"),
    ("noise sigma 50 µm/s²", msgs.SetFilter(kind=0, accel_sigma=50, p0=0, flags=0), "bad_noise"),
    ("noise sigma 20 m/s²", msgs.SetFilter(kind=0, accel_sigma=20_000_000, p0=0, flags=0),
     "bad_noise"),
    ("an unknown filter kind", msgs.SetFilter(kind=9, accel_sigma=0, p0=0, flags=0),
     "bad_value"),
    ("an unknown reset kind", msgs.Reset(kind=7), "bad_value"),
    ("a rate of 5 Hz", msgs.SetRate(rate_hz=5), "bad_value"),
]


@pytest.mark.parametrize(("what", "command", "reason"), REFUSED, ids=[r[0] for r in REFUSED])
def test_a_refused_command_names_its_reason_and_changes_nothing(
        hil_port: str, sim_url: Callable[..., str], what: str, command: object,
        reason: str) -> None:
    with open_port(sim_url(), launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=10.0)
        hello = link.handshake()
        with pytest.raises(CommandError, match=f"device refused .*: {reason}") as err:
            link.command(command)
        assert err.value.code == msgs.ErrorCode[reason.upper()]
        if reason in ("bad_calibration", "bad_noise"):
            assert "(" in str(err.value)  # the bound is named
        # Nothing changed: the board answers and says the same as before.
        again = link.handshake()
        assert (again.sample_rate_hz, again.sensors) == (hello.sample_rate_hz, hello.sensors)


def test_plausible_values_are_accepted(sim_url: Callable[..., str]) -> None:
    with open_port(sim_url(), launch=LaunchOptions(start_timeout_s=120)) as conn:
        link = Link(conn.port, timeout_s=10.0)
        link.handshake()
        link.command(calibration(s00=ONE + ONE // 50, oz=-200_000))  # S00 1.02, o_z −0.2 m/s²
        link.command(msgs.SetFilter(kind=0, accel_sigma=0, p0=0, flags=0))  # from the datasheet
        link.command(msgs.SetFilter(kind=0, accel_sigma=30_000, p0=0, flags=0))
