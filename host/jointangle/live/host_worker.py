"""`HostFilter` on a thread, so that reading the port never waits for the estimator.

`live` and `record` read the serial port in their main loop: a host filter run there would
hold each read back by its batch's compute (≈ 10 ms for 50 ms of samples at 500 Hz), and on a
busy machine by much more — long enough for the board's transmit buffer to overflow. Here the
loop only queues the board's estimates (`add`) and collects what is done (`take`): each board
estimate with the host's estimate of the sample `lag` before it, in order. The worker waits
`batch_s` after the first estimate of a batch, then runs everything queued.

The view may read the filter's plain attributes (latest, off, note, window load) at any time;
`finish` stops the thread and hands back the rest.

While it runs, OpenBLAS (numpy's and scipy's) is held to one thread: its spare threads spin
between calls, and the estimator's many small products woke them every time. Measured, live at
500 Hz with array-fls on sim://native: the live process used 98.7 % of a core with OpenBLAS's
default two threads (the estimator's own thread 0.37 ms a sample, the main loop 0.3 ms), 37.5 %
with one, for the same numbers.
"""

from __future__ import annotations

import queue
import threading
import time
from collections import deque

from threadpoolctl import threadpool_limits

from jointangle.live.host_filter import HostEstimate, HostFilter
from jointangle.live.session import Estimate

Pair = tuple[Estimate, HostEstimate | None]


class HostWorker:
    def __init__(self, host: HostFilter) -> None:
        self.host = host
        self._in: queue.SimpleQueue[list[Estimate] | None] = queue.SimpleQueue()
        self._out: deque[Pair] = deque()
        self._lock = threading.Lock()
        self.error: BaseException | None = None
        self._blas = threadpool_limits(limits=1, user_api="blas")  # (for the whole process)
        self._thread = threading.Thread(target=self._loop, name="host-filter", daemon=True)
        self._thread.start()

    def add(self, estimates: list[Estimate]) -> None:
        if estimates:
            self._in.put(estimates)

    def take(self) -> list[Pair]:
        """The pairs done since the last call, in order."""
        with self._lock:
            out = list(self._out)
            self._out.clear()
        return out

    def finish(self, timeout_s: float = 30.0) -> list[Pair]:
        """Process what is queued, stop the thread, and return every pair not taken yet."""
        self._in.put(None)
        self._thread.join(timeout_s)
        out = self.take()
        if not self._thread.is_alive():
            out += self.host.finish()
            self._blas.restore_original_limits()
        return out

    def _loop(self) -> None:
        stop = False
        while not stop:
            first = self._in.get()
            if first is None:
                return
            batch = list(first)
            deadline = time.monotonic() + self.host.batch_s
            while not stop:
                try:
                    more = self._in.get(timeout=max(0.0, deadline - time.monotonic()))
                except queue.Empty:
                    break
                if more is None:
                    stop = True
                else:
                    batch += more
            try:  # (a batch over MAX_BACKLOG_S of samples switches it off: see HostFilter.run)
                self.host.add(batch)
                pairs = self.host.run()
            except Exception as exc:  # never take the stream down with it
                self.error = exc
                self.host.off = f"host filter {self.host.name} failed: {exc}"
                pairs = [(e, None) for e in batch]
            with self._lock:
                self._out.extend(pairs)


LINE_WAIT_S = 0.25  # device time a board estimate waits for the host's before it goes without


class HostLines:
    """The board's estimates in order, each with the host's estimate once the worker has it —
    or without (None) once newer board estimates `wait_s` of device time later have arrived:
    the lines keep the board's pace when the host filter falls behind (a loaded machine, a
    board faster than real time), and the filter's own rule switches it off if it stays behind.
    """

    def __init__(self, worker: HostWorker, wait_s: float = LINE_WAIT_S) -> None:
        self.worker = worker
        self.wait_s = wait_s
        self._waiting: deque[Estimate] = deque()
        self._done: dict[int, HostEstimate | None] = {}  # by id() of a waiting estimate
        self._gone: set[int] = set()  # id() of estimates handed out before their result came
        self.without_host = 0  # estimates handed out without waiting for the host's

    def _collect(self, pairs: list[Pair]) -> None:
        for est, h in pairs:  # (each est is still referenced by the worker: its id is unique)
            if id(est) in self._gone:
                self._gone.discard(id(est))
            else:
                self._done[id(est)] = h

    def feed(self, estimates: list[Estimate]) -> list[Pair]:
        """Queue the new estimates; the ones now ready, in order."""
        self.worker.add(estimates)
        self._waiting.extend(estimates)
        self._collect(self.worker.take())
        out: list[Pair] = []
        newest = self._waiting[-1].device_s if self._waiting else 0.0
        while self._waiting:
            est = self._waiting[0]
            if id(est) in self._done:
                out.append((est, self._done.pop(id(est))))
            elif newest - est.device_s > self.wait_s:
                out.append((est, None))
                self._gone.add(id(est))
                self.without_host += 1
            else:
                break
            self._waiting.popleft()
        return out

    def finish(self) -> list[Pair]:
        """The end: the worker finishes; every waiting estimate, with its result if any."""
        self._collect(self.worker.finish())
        out = [(e, self._done.pop(id(e), None)) for e in self._waiting]
        self._waiting.clear()
        return out
