"""The guided calibration flow: pose collection, rejections, writing and EEPROM read-back."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pytest

import jointangle.cli.calibrate_guided as guided_cli
from jointangle.boards.launchers import NativeBoardLauncher
from jointangle.calibration.fit import calibration_error
from jointangle.calibration.guided import GuidedSettings, PoseCollector
from jointangle.cli.main import main
from jointangle.device.calibration_map import counts_from_readings
from jointangle.io.rig_file import load_rig, write_rig
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import encode_message
from jointangle.protocol.framing import Frame, StreamDecoder
from jointangle.protocol.link import CommandError
from jointangle.rig import Rig
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.scenarios import gravity_rig, simulate
from jointangle.sim.sensor_model import sensor_distortion
from jointangle.sim.static_poses import (
    PoseRecording,
    guided_motion_poses,
    guided_sequence,
    static_pose_recording,
    with_sensor_errors,
)

MG = STANDARD_GRAVITY * 1e-3


def _rig() -> Rig:
    return with_sensor_errors(gravity_rig(500.0), 5)


def _feed(pc: PoseCollector, rec: PoseRecording, chunk: int = 10) -> None:
    for i in range(0, len(rec.t), chunk):
        pc.feed(rec.t[i:i + chunk], rec.readings[i:i + chunk])


def test_collector_takes_every_pose_and_rejects_a_wrong_one() -> None:
    rig = _rig()
    labels = guided_sequence()
    rec = static_pose_recording(rig, guided_motion_poses(labels, mistake_at=2), seed=1,
                                hold_s=3.0, move_s=1.0, preroll_s=2.0)
    pc = PoseCollector(rig, labels)
    _feed(pc, rec)
    assert pc.done
    st = pc.state
    assert [a.label for a in st.attempts if a.accepted] == labels
    assert len(st.rejected) == 1
    bad = st.rejected[0]
    assert bad.label == "-x" and bad.axes == {"a": "+y", "b": "+y"}
    assert "has its +y axis up" in str(bad.reason) and "needs -x up" in str(bad.reason)
    report = pc.calibrate()
    assert report.accepted and [s.grade for s in report.sensors] == ["A"] * 4


def test_fixture_free_flow_takes_new_orientations_and_rejects_a_repeat() -> None:
    rig = _rig()
    labels = guided_sequence("gravity")
    assert labels[:2] == ["+z", "+x"] and labels[2:] == ["any"] * 10
    rec = static_pose_recording(rig, guided_motion_poses(labels, mistake_at=4, seed=3), seed=3,
                                hold_s=3.0, move_s=1.0, preroll_s=2.0)
    pc = PoseCollector(rig, labels)
    _feed(pc, rec)
    assert pc.done and len(pc.state.rejected) == 1
    assert "only 0° from pose 4" in str(pc.state.rejected[0].reason)
    report = pc.calibrate(method="gravity")
    assert report.accepted, report.reasons()
    for s, (_, _, cfg) in zip(report.sensors, rig.all_sensors(), strict=True):
        m, bias = sensor_distortion(cfg)
        assert s.S is not None and s.offset is not None
        e_mat, e_off = calibration_error(s.S, s.offset, m, bias)
        assert np.abs(np.diag(e_mat)).max() < 0.005 and np.abs(e_off).max() < 5 * MG


def test_collector_rejects_a_creeping_hold_then_takes_the_pose() -> None:
    rig = _rig()
    labels = guided_sequence()
    poses = guided_motion_poses(labels)
    poses.insert(1, poses[1])  # +x held twice: the first hold creeps
    rec = static_pose_recording(rig, poses, seed=2, hold_s=3.0, move_s=1.0, preroll_s=2.0)
    a, b = rec.holds[1]
    sl = slice(round(a * 500), round(b * 500))
    ramp = np.linspace(0.0, 60 * MG, sl.stop - sl.start)  # 60 mg over the hold, every sensor
    readings = rec.readings.copy()
    readings[sl, :, 1] += ramp[:, None]
    rec = PoseRecording(rec.rig, rec.t, readings, rec.f_link, rec.poses, rec.holds)
    # Hold 1 s, settle 1.5 s: within the 3 s hold the creep is seen and reported.
    pc = PoseCollector(rig, labels, GuidedSettings(hold_s=1.0))
    _feed(pc, rec)
    assert pc.done
    crept = [x for x in pc.state.rejected if "crept" in str(x.reason)]
    assert crept and all(x.label == "+x" for x in pc.state.rejected)
    assert pc.calibrate().accepted


# ---- the CLI against a fake board: a poor fit is rejected and nothing is written ----

@dataclass
class FakeLink:
    """Acks every command; keeps what set_calibration sent and answers get_calibration with it
    (`flip` alters one stored value; `refuse_save` fails save_eeprom)."""

    sent: list[msgs.Message] = field(default_factory=list)
    refuse_save: bool = False
    flip: bool = False
    hello: msgs.Hello | None = None
    _stored: dict[int, msgs.SetCalibration] = field(default_factory=dict)
    _answer: list[Frame] = field(default_factory=list)

    def command(self, msg: msgs.Message, *, timeout_s: float | None = None) -> msgs.Ack:
        self.sent.append(msg)
        if isinstance(msg, msgs.SaveEeprom) and self.refuse_save:
            raise CommandError("save_eeprom", msgs.ErrorCode.EEPROM_FAILED)
        if isinstance(msg, msgs.SetCalibration):
            self._stored[msg.slot] = msg
        if isinstance(msg, msgs.GetCalibration):
            st = self._stored[msg.slot]
            vals = {f: getattr(st, f) for f in ("s00", "s01", "s02", "s10", "s11", "s12",
                                                "s20", "s21", "s22", "ox", "oy", "oz")}
            if self.flip and msg.slot == 2:
                vals["oy"] += 1
            cal = msgs.Calibration(slot=msg.slot, source=msg.source, **vals)
            self._answer = StreamDecoder().feed(encode_message(cal, 0, 0))
        return msgs.Ack(command_id=msg.MSG_ID, command_seq=0, error=0)

    def poll(self) -> list[Frame]:
        out, self._answer = self._answer, []
        return out

    def handshake(self) -> msgs.Hello:
        assert self.hello is not None
        return self.hello


class FakeStream:
    """Plays a recording as sample_estimate frames, 20 per poll."""

    recording: PoseRecording
    last: FakeStream | None = None
    link_options: ClassVar[dict[str, bool]] = {}

    def __init__(self, url: str | None, **_: Any) -> None:
        self.url = url
        self.link = FakeLink(**self.link_options)
        self.streaming = False
        rec = self.recording
        counts = counts_from_readings(rec.rig, rec.readings)
        dec = StreamDecoder()
        self.frames: list[Frame] = []
        for k in range(len(rec.t)):
            m = msgs.SampleEstimate(theta=0, omega_a=0, omega_b=0, health=1, sensors=tuple(
                msgs.SampleEstimateSensor(x=int(c[0]), y=int(c[1]), z=int(c[2]), fresh=1,
                                          status=0) for c in counts[k]))
            self.frames += dec.feed(encode_message(m, k & 0xFFFF, k * 2000))
        FakeStream.last = self

    @property
    def resolved_url(self) -> str:
        return str(self.url)

    def connect(self) -> msgs.Hello:
        sensors = tuple(msgs.HelloSensor(link=0 if ln == "a" else 1, model=1, mux_channel=0,
                                         address=0x53, chip_id=0xE5, range_g=s.range_g,
                                         status=0)
                        for ln, _, s in self.recording.rig.all_sensors())
        self.link.hello = msgs.Hello(protocol_version=msgs.PROTOCOL_VERSION,
                                     schema_hash=msgs.SCHEMA_HASH, firmware_major=0,
                                     firmware_minor=1, firmware_patch=0,
                                     build=b"fake".ljust(12, b"\0"), board=0,
                                     sample_rate_hz=500, stream_mode=0, eeprom=0,
                                     sensors=sensors)
        return msgs.Hello(protocol_version=msgs.PROTOCOL_VERSION, schema_hash=msgs.SCHEMA_HASH,
                          firmware_major=0, firmware_minor=1, firmware_patch=0,
                          build=b"fake".ljust(12, b"\0"), board=0, sample_rate_hz=500,
                          stream_mode=0, eeprom=0, sensors=sensors)

    def start(self) -> None:
        self.streaming = True

    def poll(self) -> list[Frame]:
        out, self.frames = self.frames[:20], self.frames[20:]
        return out

    def stop(self) -> list[Frame]:
        return []


def test_poor_fit_is_rejected_with_the_reason_and_nothing_is_written(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    rig = _rig()
    rig_file = tmp_path / "rig.toml"
    write_rig(rig, rig_file)
    labels = guided_sequence()
    rec = static_pose_recording(rig, guided_motion_poses(labels), seed=3, hold_s=3.0,
                                move_s=1.0, preroll_s=1.0)
    # Sensor a.1 slipped in its mount during the -y hold: 80 mg more on x there only.
    a, b = rec.holds[4]
    readings = rec.readings.copy()
    readings[round(a * 500):round(b * 500), 1, 0] += 80 * MG
    FakeStream.recording = PoseRecording(rec.rig, rec.t, readings, rec.f_link, rec.poses,
                                         rec.holds)
    FakeStream.link_options = {}
    monkeypatch.setattr(guided_cli, "DeviceStream", FakeStream)
    before = rig_file.read_text()
    code = main(["calibrate", "--port", "fake://board", "--rig", str(rig_file), "--yes",
                 "--hold", "1.5", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 1
    assert not doc["accepted"] and not doc["written"] and doc["rig_out"] is None
    assert any(r.startswith("a.1: residual too large") for r in doc["reasons"])
    link = FakeStream.last.link if FakeStream.last else None
    assert link is not None
    assert not any(isinstance(m, msgs.SetCalibration | msgs.SaveEeprom) for m in link.sent)
    assert rig_file.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.toml"]


@pytest.mark.parametrize(("option", "why"), [("refuse_save", "eeprom_failed"),
                                             ("flip", "EEPROM read-back differs for slot 2")])
def test_a_board_that_does_not_store_it_fails_and_the_rig_file_is_left_alone(
        option: str, why: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    rig = _rig()
    rig_file = tmp_path / "rig.toml"
    write_rig(rig, rig_file)
    FakeStream.recording = static_pose_recording(rig, guided_motion_poses(guided_sequence()),
                                                 seed=4, hold_s=3.0, move_s=1.0, preroll_s=1.0)
    FakeStream.link_options = {option: True}
    monkeypatch.setattr(guided_cli, "DeviceStream", FakeStream)
    code = main(["calibrate", "--port", "fake://board", "--rig", str(rig_file), "--yes",
                 "--hold", "1.5", "--json"])
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert code == 1 and doc["accepted"] and doc["rig_out"] is None
    assert why in doc["error"] and "did not store the calibration" in captured.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.toml"]


# ---- end to end against the native virtual board ----

def test_guided_flow_end_to_end_on_the_native_board(tmp_path: Path) -> None:
    """Scripted: the board plays the seven poses with one mistaken hold; the flow rejects it,
    fits, asks for confirmation (y + Enter on stdin), writes, saves, reads back from EEPROM.
    The board's clock runs in real time until the stream starts, then as fast as the host
    reads (fast=1): the 10 s of handling first leave a loaded machine time to connect."""
    NativeBoardLauncher().find_binary(build=True)  # fails with how to build it
    src = tmp_path / "rig.toml"
    write_rig(gravity_rig(500.0), src)
    out = tmp_path / "out.toml"
    before = src.read_text()
    proc = subprocess.run(
        [sys.executable, "-m", "jointangle", "calibrate", "--port", "sim://native?fast=1", "--rig",
         str(src), "--inject-errors", "7", "--sim-mistake", "3", "--hold", "1.0",
         "--sim-hold", "2.0", "--sim-preroll", "10", "--out", str(out), "--json"],
        input="y\n", capture_output=True, text=True, timeout=180, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    doc = json.loads(proc.stdout)
    assert "REJECTED" in proc.stderr and "HOLD" not in proc.stderr  # non-interactive log
    assert doc["rejected_poses"] == 1
    bad = [a for a in doc["attempts"] if not a["accepted"]]
    assert bad[0]["pose"] == "-x" and "needs -x up" in bad[0]["reason"]
    assert [a["pose"] for a in doc["attempts"] if a["accepted"]] == guided_sequence()
    assert doc["accepted"] and doc["written"]
    assert [r["confirmed"] for r in doc["readback"]] == [True] * 4
    assert all(r["sent"] == r["stored"] for r in doc["readback"])
    assert src.read_text() == before  # the original rig is untouched
    cal = load_rig(out)
    for _, _, s in cal.all_sensors():
        assert s.S is not None and s.offset is not None
        m, bias = sensor_distortion(s)
        e_mat, e_off = calibration_error(np.asarray(s.S), np.asarray(s.offset), m, bias)
        # Injected: up to 5 % scale, 100 mg/g cross-axis, 3°, 100 mg offsets; left: ~noise.
        assert np.abs(np.diag(e_mat)).max() < 0.005
        assert np.abs(e_off).max() < 5 * MG


def test_guided_motion_step_on_the_native_board(tmp_path: Path) -> None:
    """The poses, then 25 s of free motion: the native board takes every set_sensor and
    set_joint of the fitted geometry, saves it, and its calibrations read back unchanged."""
    NativeBoardLauncher().find_binary(build=True)
    src = tmp_path / "rig.toml"
    write_rig(gravity_rig(500.0), src)
    out = tmp_path / "out.toml"
    proc = subprocess.run(
        [sys.executable, "-m", "jointangle", "calibrate", "--port", "sim://native?fast=1", "--rig",
         str(src), "--hold", "1.0", "--sim-hold", "2.0", "--sim-preroll", "10",
         "--motion-seconds", "25", "--mounting-tolerance-deg", "0.2", "--out", str(out),
         "--json"], input="y\n", capture_output=True, text=True, timeout=240, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    doc = json.loads(proc.stdout)
    assert doc["written"] and doc["motion"]["accepted"] and doc["motion"]["written"]
    assert abs(doc["motion"]["reference"]["offset_deg"]) < 0.1
    drawn, fitted = gravity_rig(500.0), load_rig(out)
    for ln in ("a", "b"):
        for s0, s1 in zip(drawn.links[ln].sensors, fitted.links[ln].sensors, strict=True):
            lever0 = np.subtract(s0.position, drawn.links[ln].joint)
            lever1 = np.subtract(s1.position, fitted.links[ln].joint)
            assert np.hypot(*(lever1 - lever0)) < 1e-3  # built as drawn: stays within 1 mm
            assert s1.S is not None


def test_the_original_rig_file_is_never_lost(tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    rig = tmp_path / "bench.toml"
    rig.write_text("x")
    # Default: a new file next to the rig, numbered when one exists already.
    assert guided_cli._output_path(rig, None) == (tmp_path / "bench.calibrated.toml", None)
    (tmp_path / "bench.calibrated.toml").write_text("y")
    assert guided_cli._output_path(rig, None)[0] == tmp_path / "bench.calibrated-2.toml"
    # --out naming the rig itself: the original is copied aside first.
    assert guided_cli._output_path(rig, str(rig)) == (rig, tmp_path / "bench.orig.toml")
    # --out elsewhere: written there; no rig file (a virtual board's): rig.calibrated.toml.
    assert guided_cli._output_path(rig, str(tmp_path / "o.toml")) == (tmp_path / "o.toml", None)
    monkeypatch.chdir(tmp_path)
    assert guided_cli._output_path(None, None) == (tmp_path / "rig.calibrated.toml", None)


def test_big_batches_give_the_same_poses_as_small_ones() -> None:
    """A host that falls behind reads the stream in big chunks: every sample is still tested."""
    rig = _rig()
    labels = guided_sequence()
    rec = static_pose_recording(rig, guided_motion_poses(labels, mistake_at=2), seed=1,
                                hold_s=3.0, move_s=1.0, preroll_s=2.0)
    small = PoseCollector(rig, labels)
    _feed(small, rec, chunk=10)
    big = PoseCollector(rig, labels)
    _feed(big, rec, chunk=1000)
    assert big.done and [(a.label, a.accepted) for a in big.state.attempts] == [
        (a.label, a.accepted) for a in small.state.attempts]


# ---- the motion step: geometry from free motion, the joint's zero, written to the board ----

def _poses_then(rig: Rig, motion: np.ndarray) -> PoseRecording:
    rec = static_pose_recording(rig, guided_motion_poses(guided_sequence()), seed=6, hold_s=3.0,
                                move_s=1.0, preroll_s=1.0)
    t = np.concatenate([rec.t, rec.t[-1] + (1 + np.arange(len(motion))) / 500.0])
    return PoseRecording(rec.rig, t, np.concatenate([rec.readings, motion]), rec.f_link,
                         rec.poses, rec.holds)


def test_motion_step_fits_the_geometry_and_writes_it_to_the_board(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """Sensor b.1 sits 1.5 mm further out than the rig file says: after the poses, 30 s of free
    motion put its lever arm back within 0.5 mm, and the board gets every set_sensor and
    set_joint (b.1's x as fitted), the calibrations again and save_eeprom."""
    from dataclasses import replace

    # No sensor errors here: a scale error the static fit leaves (~0.3 %) moves a 27.5 cm lever
    # arm by ~0.8 mm (the centripetal reading is ω² r times the scale).
    rig = gravity_rig(500.0)
    lb = rig.links["b"]
    true_rig = replace(rig, links={**rig.links, "b": replace(lb, sensors=(
        lb.sensors[0], replace(lb.sensors[1], sim_position_offset_m=(0.0015, 0.0))))})
    rig_file = tmp_path / "rig.toml"
    write_rig(rig, rig_file)
    free = simulate("gravity-free-motion", seed=6, rate_hz=500.0, seconds=35.0, rig=true_rig)
    FakeStream.recording = _poses_then(true_rig, free.readings)
    FakeStream.link_options = {}
    monkeypatch.setattr(guided_cli, "DeviceStream", FakeStream)
    out = tmp_path / "out.toml"
    code = main(["calibrate", "--port", "fake://board", "--rig", str(rig_file), "--yes",
                 "--hold", "1.5", "--motion-seconds", "30", "--mounting-tolerance-deg", "0.5",
                 "--out", str(out), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0, doc.get("motion")
    assert doc["motion"]["accepted"] and doc["motion"]["written"]
    assert doc["motion"]["reference"]["accepted"]
    assert abs(doc["motion"]["reference"]["offset_deg"]) < 0.1
    fitted = load_rig(out)
    lever = fitted.links["b"].sensors[1].position[0] - fitted.links["b"].joint[0]
    truth = lb.sensors[1].position[0] + 0.0015 - lb.joint[0]
    assert abs(lever - truth) < 0.5e-3
    assert fitted.links["a"].sensors[0].S is not None  # the sensor calibration kept
    link = FakeStream.last.link if FakeStream.last else None
    assert link is not None
    set_sensors = [m for m in link.sent if isinstance(m, msgs.SetSensor)]
    assert len(set_sensors) == 4
    assert set_sensors[3].x == round(fitted.links["b"].sensors[1].position[0] * 1e6)
    assert sum(isinstance(m, msgs.SetJoint) for m in link.sent) == 2
    assert isinstance(link.sent[-1], msgs.GetCalibration)
    assert sum(isinstance(m, msgs.SaveEeprom) for m in link.sent) == 2


def test_a_still_motion_step_writes_no_geometry(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    rig = _rig()
    rig_file = tmp_path / "rig.toml"
    write_rig(rig, rig_file)
    still = simulate("gravity-reference-pose", seed=6, rate_hz=500.0, seconds=30.0, rig=rig)
    FakeStream.recording = _poses_then(rig, still.readings)
    FakeStream.link_options = {}
    monkeypatch.setattr(guided_cli, "DeviceStream", FakeStream)
    out = tmp_path / "out.toml"
    code = main(["calibrate", "--port", "fake://board", "--rig", str(rig_file), "--yes",
                 "--hold", "1.5", "--motion-seconds", "25", "--out", str(out), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 1
    assert doc["written"] and not doc["motion"]["accepted"]
    assert any("hardly turned" in r for r in doc["motion"]["reasons"])
    link = FakeStream.last.link if FakeStream.last else None
    assert link is not None
    assert not any(isinstance(m, msgs.SetSensor | msgs.SetJoint) for m in link.sent)
    # the rig file says what the board holds: the sensor calibration, the drawn geometry
    written = load_rig(out)
    assert written.links["b"].sensors[1].position == rig.links["b"].sensors[1].position
    assert written.links["b"].sensors[1].S is not None
