"""Keeps a virtual board from outliving the host that started it (issue 16 item 5).

    python -I -S guard.py WORKDIR -- BOARD_ARGV...

`process.start_process_board` runs every virtual board through this guard. The guard starts
the board with its own standard output and error (the host reads `PTY <path>` from them as
before) and watches its standard input, a pipe whose write end only the host holds: when the
host dies -- by any signal, SIGKILL included, as the kernel closes a dead process's files -- the
guard reads end-of-file at once, stops the board (SIGTERM, then SIGKILL after a second) and
removes the board's work folder (WORKDIR; "-" for none). SIGTERM to the guard (the host's
normal stop) does the same. The guard then exits with the board's status (or by its signal).

It is a separate process rather than PR_SET_PDEATHSIG on the board: a death signal follows the
thread that forked the board, not the host process (a board started from a worker thread would
be killed when that thread ends), and it could not remove the folder. Standard library only, no
jointangle import: it starts in ~20 ms.
"""

from __future__ import annotations

import os
import select
import shutil
import signal
import subprocess
import sys

STOP_WAIT_S = 1.0  # SIGTERM, then SIGKILL after this long


def _stop(board: subprocess.Popen[bytes]) -> None:
    if board.poll() is None:
        board.send_signal(signal.SIGTERM)
        try:
            board.wait(STOP_WAIT_S)
        except subprocess.TimeoutExpired:
            board.kill()
            board.wait()


def main(argv: list[str]) -> int:
    if len(argv) < 3 or argv[1] != "--":
        sys.stderr.write("usage: guard.py WORKDIR -- BOARD_ARGV...\n")
        return 2
    workdir, board_argv = argv[0], argv[2:]
    stop = False

    def on_term(signum: int, frame: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, on_term)
    try:
        board = subprocess.Popen(board_argv, stdin=subprocess.DEVNULL)
    except OSError as exc:
        sys.stderr.write(f"cannot start {board_argv[0]}: {exc.strerror}\n")
        if workdir != "-":
            shutil.rmtree(workdir, ignore_errors=True)
        return 127
    # Ctrl-C reaches the whole process group: the host decides (it stops us with SIGTERM).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # The boards' own control signals (SIGUSR1: open the measurement window, as `bench
    # firmware` sends it) are passed on.
    for forwarded in (signal.SIGUSR1, signal.SIGUSR2):
        signal.signal(forwarded, lambda signum, frame: board.send_signal(signum))
    while not stop and board.poll() is None:
        ready, _, _ = select.select([0], [], [], 0.1)
        if ready and not os.read(0, 4096):
            break  # end of file: the host is gone
    _stop(board)
    if workdir != "-":
        shutil.rmtree(workdir, ignore_errors=True)
    code = board.returncode
    if code < 0:  # died by a signal: so does the guard (the host sees the same status)
        signal.signal(-code, signal.SIG_DFL)
        os.kill(os.getpid(), -code)
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
