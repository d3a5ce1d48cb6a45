"""The command line starts where the POSIX-only modules are missing (Windows: termios, tty,
fcntl, pty, grp, pwd, resource), issue 18 item 2: none is imported at module level by the host;
those that need one import it where it is used (`live`'s keys, `doctor`'s groups)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

POSIX_ONLY = ("termios", "tty", "fcntl", "pty", "grp", "pwd", "resource")

# pyserial picks its backend by os.name, so it is imported first (on Windows it would load
# serialwin32); then the POSIX-only modules are made unimportable and the whole command line
# (every subcommand's module) is built and run.
PROBE = f"""
import sys
import serial, serial.tools.list_ports  # noqa: F401
for name in {POSIX_ONLY!r}:
    sys.modules.pop(name, None)
    sys.modules[name] = None
from jointangle.cli.main import build_parser, main
build_parser()
sys.exit(main(sys.argv[1:]))
"""


def run(*argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True,
                          timeout=120, check=False)


def test_the_command_line_starts_without_posix_only_modules(tmp_path: Path) -> None:
    res = run("simulate", "--scenario", "gravity-ramp", "--seconds", "1", "--out",
              str(tmp_path / "d.csv"), "--rig-out", str(tmp_path / "r.toml"))
    assert res.returncode == 0, res.stderr
    res = run("estimate", "--rig", str(tmp_path / "r.toml"), "--input", str(tmp_path / "d.csv"),
              "--filter", "array-ekf", "--out", str(tmp_path / "e.csv"))
    assert res.returncode == 0, res.stderr
    res = run("doctor", "--json", "--port", "socket://localhost:1")
    assert res.returncode in (0, 1) and '"findings"' in res.stdout, res.stderr
