"""Two hosts on one port (issue 16 item 4): the second is refused at open, in under a second,
with one line naming the port; the first recording loses nothing."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_runs import one_line_error
from fake_device import FakeData, FakeDevice

from jointangle.cli.main import build_parser, main


def test_a_second_host_on_the_same_port_is_refused_and_the_first_loses_nothing(
        tmp_path: Path, fake_data: tuple[FakeData, str], rig_file: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    first = tmp_path / "first.jrec"
    with FakeDevice(fake_data[0], tmp_path) as fake:
        proc = subprocess.Popen(
            [sys.executable, "-m", "jointangle", "record", "--port", str(fake.path), "--seconds",
             "3", "--out", str(first), "--rig", str(rig_file), "--json", "--retries", "0"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            deadline = time.monotonic() + 30
            while "start_stream" not in fake.counts.commands:  # the first one is recording
                assert time.monotonic() < deadline and proc.poll() is None
                time.sleep(0.05)
            build_parser()  # the commands' modules imported: time the refusal, not imports
            capsys.readouterr()
            for argv in (["record", "--port", str(fake.path), "--seconds", "1", "--out",
                          str(tmp_path / "second.jrec")],
                         ["live", "--port", str(fake.path), "--seconds", "1", "--json"],
                         ["info", "--port", str(fake.path)]):
                t0 = time.monotonic()
                assert main(argv) == 2
                took = time.monotonic() - t0
                assert took < 1.0, (argv[0], took)
                one_line_error(capsys.readouterr().err, str(fake.path), "in use",
                               "jointangle record")  # names the holder
            assert not (tmp_path / "second.jrec").exists()
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        assert proc.returncode == 0, err.decode()
        commands = fake.counts.commands
    doc = json.loads(out)
    assert doc["complete"] and doc["disconnects"] == 0
    assert doc["frames_lost"] == 0 and doc["crc_errors"] == 0 and doc["bytes_skipped"] == 0
    assert commands.count("get_info") == 1  # the refused hosts never wrote to the device
    capsys.readouterr()
    assert main(["replay", str(first), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["frames"] == doc["frames"] and rep["frames_lost"] == 0
    assert rep["messages"]["sample_estimate"] == doc["samples"] > 1000


def test_a_port_held_by_another_process_is_named(tmp_path: Path) -> None:
    import fcntl
    import os
    import tty

    from jointangle.errors import InputError
    from jointangle.transport import open_serial

    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    fcntl.flock(slave, fcntl.LOCK_EX | fcntl.LOCK_NB)  # as another jointangle would hold it
    try:
        with pytest.raises(InputError, match=f"{path} is in use by another program"):
            open_serial(path)
        fcntl.flock(slave, fcntl.LOCK_UN)
        open_serial(path).close()  # free again: opens
    finally:
        os.close(slave)
        os.close(master)
