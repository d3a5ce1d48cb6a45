"""The live view on the native virtual board, in a real 80×24 terminal (tmux), keys included.

Needs tmux (installed by scripts/setup.sh) and the `ja_native_board` target (built by
scripts/test.sh before pytest); without them the test fails and says which is missing.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def _board() -> Path:
    found = sorted(ROOT.glob("build/*/firmware/**/ja_native_board"))
    assert found, ("ja_native_board is not built: "
                   "cmake --build build/native --target ja_native_board")
    return found[0]


def _capture(session: str) -> str:
    return subprocess.run(["tmux", "capture-pane", "-t", session, "-p"], check=True,
                          capture_output=True, text=True).stdout


def test_live_view_renders_in_80x24_and_quits_on_q(tmp_path: Path) -> None:
    assert shutil.which("tmux"), "tmux is missing (scripts/setup.sh installs it)"
    _board()
    session = f"ja-live-{uuid.uuid4().hex[:8]}"
    jointangle = Path(sys.executable).with_name("jointangle")
    done = tmp_path / "exit_status"
    cmd = f"cd {tmp_path} && {jointangle} live --port sim://native; echo $? > {done}"
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "80", "-y", "24", cmd],
                   check=True)
    try:
        screen = ""
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:
            screen = _capture(session)
            if "rate" in screen and "500" in screen and "sensors:" in screen:
                break
            time.sleep(0.5)
        lines = screen.splitlines()
        assert len(lines) <= 24 and all(len(ln) <= 80 for ln in lines), screen
        assert "jointangle live" in screen and "θ" in screen, screen
        assert "a0 ok" in screen and "b1 ok" in screen, screen
        assert "lost 0" in screen, screen
        subprocess.run(["tmux", "send-keys", "-t", session, "q"], check=True)
        deadline = time.monotonic() + 20
        while not done.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert done.exists() and done.read_text().strip() == "0"
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)
