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
            try:
                self.host.add(batch)
                pairs = self.host.run()
            except Exception as exc:  # never take the stream down with it
                self.error = exc
                self.host.off = f"host filter {self.host.name} failed: {exc}"
                pairs = [(e, None) for e in batch]
            with self._lock:
                self._out.extend(pairs)
