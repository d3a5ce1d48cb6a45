"""A streaming session with a device that survives a pulled cable (docs/design.md §6).

`DeviceStream` opens the port (transport.open_port), shakes hands, starts the stream and hands
out decoded frames. Every byte read goes to the recorder first (through the Link's hook), so a
recording holds exactly what arrived. When the port fails (a read error, end of file, or no byte
for `stall_s` while streaming) the session counts a disconnect, closes the port and tries to
reopen the same device `retries` times, `retry_delay_s` apart (the same address; for a virtual
board the pty it serves now, without starting another board); on success it shakes hands again
and restarts the stream in the same mode, appending to the same recording.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import serial

from jointangle.boards.options import DEFAULT_BAUD, LaunchOptions
from jointangle.errors import InputError
from jointangle.protocol import messages as msgs
from jointangle.protocol.framing import (
    COUNT_KEYS,
    Frame,
    ProtocolMismatchError,
    StreamDecoder,
    merge_versions,
)
from jointangle.protocol.link import (
    CommandError,
    Link,
    LinkTimeoutError,
    Recorder,
)
from jointangle.transport import Connection, open_port

HANDSHAKE_TRIES = 3  # an Arduino resets when the port opens: its bootloader takes ~1-2 s
DEFAULT_MODE = msgs.StreamMode.SAMPLE_ESTIMATE | msgs.StreamMode.STATUS
# What the host asks the board to stream (--stream): `full` = every sensor's raw counts with the
# estimate (the firmware-vs-mirror divergence, host filters and replay --verify need them);
# `estimates` = lean_estimate frames (estimate, health, fault mask: 27 bytes on the wire against
# ~70 with four sensors), for slow links such as 115 200 baud or a Bluetooth serial module.
STREAM_CONTENTS = MappingProxyType({
    "full": int(DEFAULT_MODE),
    "estimates": int(msgs.StreamMode.LEAN_ESTIMATE | msgs.StreamMode.STATUS),
})


@contextlib.contextmanager
def interrupt_flag() -> Iterator[Callable[[], bool]]:
    """Ctrl-C (SIGINT) sets a flag instead of raising KeyboardInterrupt wherever the program
    happens to be: a KeyboardInterrupt between reading a chunk from the port and recording it
    lost that chunk (~60 frames). The streaming loops check the flag between polls. SIGTERM
    (`kill`, `timeout`, systemd) and SIGHUP (the terminal or tmux closed) do the same: without
    it they ended the host at once and left a virtual board it had started running, with its
    folder. Outside the main thread (no signal handlers there) it never fires."""
    hit = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield hit.is_set
        return
    stops = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    old = {s: signal.getsignal(s) for s in stops}
    for s in stops:
        signal.signal(s, lambda *_: hit.set())
    try:
        yield hit.is_set
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)


class DeviceLostError(RuntimeError):
    """The device went away and did not come back within the retries."""


class BufferedRecorder:
    """Keeps chunks (with their receive times) until a writer exists, then passes them on.

    The recording's metadata needs the hello, which arrives after the first bytes: this lets the
    Link record from the very first byte anyway."""

    def __init__(self) -> None:
        self._held: list[tuple[int, bytes]] | None = []  # None: not holding (discard)
        self._target: Recorder | None = None

    def write(self, data: bytes, host_ns: int | None = None) -> None:
        t = time.time_ns() if host_ns is None else host_ns
        if self._target is not None:
            self._target.write(data, t)
        elif self._held is not None:
            self._held.append((t, bytes(data)))

    def attach(self, target: Recorder | None) -> None:
        """Pass everything held, and from now on every chunk, to `target`; None stops holding
        and discards (a live view that is not recording)."""
        self._target = target
        if target is not None and self._held:
            for t, data in self._held:
                target.write(data, t)
        self._held = None


def _port_errors() -> tuple[type[Exception], ...]:
    return (serial.SerialException, OSError)


@dataclass
class DeviceStream:
    url: str | None
    baud: int = DEFAULT_BAUD
    mode: int = int(DEFAULT_MODE)
    status_interval_ms: int = 1000
    every: int = 1  # the per-loop frames every Nth loop (--every)
    retries: int = 5
    retry_delay_s: float = 0.5
    stall_s: float = 2.0
    handshake_timeout_s: float = 1.0
    launch: LaunchOptions | None = None
    opener: Callable[..., Connection] = open_port
    recorder: BufferedRecorder = field(default_factory=BufferedRecorder)
    on_event: Callable[[str], None] | None = None
    # state
    connection: Connection | None = None
    link: Link | None = None
    hello: msgs.Hello | None = None
    streaming: bool = False
    filter_restarted: bool = False  # the session restarted the board's filter (and does again
    # after every reconnect)
    disconnects: int = 0
    reconnects: int = 0
    _closed_stats: dict[str, int] = field(default_factory=dict)
    _closed_versions: dict[int, int] = field(default_factory=dict)
    _last_rx: float = 0.0
    _previous: StreamDecoder | None = None  # the decoder of the link before a loss

    @property
    def resolved_url(self) -> str:
        return self.connection.url if self.connection else (self.url or "")

    def connect(self) -> msgs.Hello:
        """Open the port and shake hands (several tries: boards reset when opened). After a
        loss, the same connection's device is reopened (a virtual board keeps running)."""
        first = self.connection is None
        if self.connection is None:
            self.connection = self.opener(self.url, baud=self.baud, launch=self.launch)
        else:
            self.connection.reopen()
        self.url = self.connection.url
        self.link = Link(self.connection.port, recorder=self.recorder,
                         timeout_s=self.handshake_timeout_s)
        # After a loss the device's sequence counter went on: the frames it sent meanwhile
        # count as lost, as replay counts them in the recording (a restart's hello seq 0 not).
        if self._previous is not None:
            self.link.decoder.continue_after(self._previous)
        last: Exception | None = None
        for _ in range(HANDSHAKE_TRIES):
            try:
                self.hello = self.link.handshake()
                self._last_rx = time.monotonic()
                return self.hello
            except LinkTimeoutError as exc:
                last = exc
            except ProtocolMismatchError:
                self._close_port(final=first)
                raise
            except _port_errors() as exc:
                self._close_port(final=first)
                raise InputError(f"{self.url}: {exc}", field="--port") from None
        self._close_port(final=first)
        raise InputError(f"{self.url}: the device did not answer get_info ({last}); is it "
                         "running the jointangle firmware at this baud rate?", field="--port")

    def start(self) -> None:
        assert self.link is not None
        self.link.command(msgs.StartStream(mode=self.mode,
                                           status_interval_ms=self.status_interval_ms,
                                           every=self.every))
        self.streaming = True
        self._last_rx = time.monotonic()

    def restart_filter(self) -> None:
        """Restart the device's filter with the settings it has (restart_filter), so its
        estimates start from a known state that the mirror and `replay --verify` follow from
        that frame on."""
        assert self.link is not None
        self.link.command(msgs.RestartFilter())
        self.filter_restarted = True

    @property
    def stats(self) -> dict[str, int]:
        out = dict(self._closed_stats)
        if self.link is not None:
            for k, v in self.link.stats.items():
                out[k] = out.get(k, 0) + v
        return out

    @property
    def versions_seen(self) -> dict[str, int]:
        """Frames with a good CRC per protocol version byte, over every connection."""
        out = dict(self._closed_versions)
        if self.link is not None:
            merge_versions(out, self.link.decoder.stats.versions_seen)
        return {str(v): n for v, n in sorted(out.items())}

    def _event(self, text: str) -> None:
        if self.on_event is not None:
            self.on_event(text)

    def _close_port(self, *, final: bool = False) -> None:
        """Close the port; `final` also ends the connection (stops a virtual board)."""
        if self.link is not None:
            if final:
                self.link.decoder.finish()  # the input ended: a frame still held is stale
            for k, v in self.link.stats.items():
                self._closed_stats[k] = self._closed_stats.get(k, 0) + v
            merge_versions(self._closed_versions, self.link.decoder.stats.versions_seen)
            if self.link.decoder.last_seq is not None:
                self._previous = self.link.decoder
            self.link = None
        if self.connection is not None:
            try:
                if final:
                    self.connection.close()
                else:
                    self.connection.close_port()
            except _port_errors():
                pass
            if final:
                self.connection = None

    def poll(self) -> list[Frame]:
        """Frames that arrived; reconnects transparently (DeviceLostError when it cannot)."""
        if self.link is None:
            self._reconnect()
            return []
        try:
            frames = self.link.poll()
        except _port_errors() as exc:
            self._lost(f"port error: {exc}")
            return []
        now = time.monotonic()
        if frames:
            self._last_rx = now
        elif self.streaming and now - self._last_rx > self.stall_s:
            self._lost(f"no data for {self.stall_s:.1f} s")
            return []
        return frames

    def _lost(self, why: str) -> None:
        self.disconnects += 1
        self._event(f"device lost ({why}); reconnecting…")
        self._close_port()
        self._reconnect()

    def _reconnect(self) -> None:
        was_streaming = self.streaming
        for attempt in range(1, self.retries + 1):
            time.sleep(self.retry_delay_s)
            try:
                self.connect()
                if was_streaming:
                    self.start()
                if self.filter_restarted:
                    # The session started the board's filter: start it again, so that what
                    # follows the gap is a filter run of its own that the mirror (and replay
                    # --verify) follows from its first step, segment by segment.
                    self.restart_filter()
            except ProtocolMismatchError:
                raise
            except (InputError, LinkTimeoutError, CommandError) as exc:
                self._close_port()
                self._event(f"reconnect {attempt}/{self.retries} failed: {exc}")
                continue
            except _port_errors() as exc:
                self._close_port()
                self._event(f"reconnect {attempt}/{self.retries} failed: {exc}")
                continue
            self.reconnects += 1
            self._event("reconnected")
            return
        self.streaming = False
        self._close_port(final=True)
        raise DeviceLostError(f"the device on {self.url} did not come back after {self.retries} "
                              "tries")

    def stop(self) -> list[Frame]:
        """Stop the stream (best effort) and close the port; returns the frames that arrived
        meanwhile."""
        left: list[Frame] = []
        if self.link is not None and self.streaming:
            try:
                self.link.command(msgs.StopStream(), timeout_s=0.5)
            except (LinkTimeoutError, CommandError):
                pass  # closing anyway; whatever arrived until now is recorded
            except _port_errors():
                pass
            try:
                left = self.link.poll()
            except _port_errors():
                pass
        self.streaming = False
        self._close_port(final=True)
        return left

    def summary(self) -> dict[str, Any]:
        st = self.stats
        return {**{k: st.get(k, 0) for k in COUNT_KEYS}, "versions_seen": self.versions_seen,
                "disconnects": self.disconnects, "reconnects": self.reconnects}
