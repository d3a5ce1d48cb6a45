"""Sequence accounting of a device's frames: serial-number arithmetic with a window (RFC 3550
appendix A.1, as RTP and MAVLink receivers do), shared by the streaming and bulk decoders.

The device numbers its frames with a 16-bit counter. The receiver keeps `top`, the newest
sequence number of the current *segment* (extended past 16 bits), and classifies each accepted
frame by its distance d = seq - top, taken modulo 2^16 into -32768..32767:

- 0 < d <= FORWARD_WINDOW: in order; the d - 1 numbers skipped are counted in `frames_lost`
  (and remembered for REORDER_WINDOW frames, in case they still come).
- -REORDER_WINDOW < d < 0 and the number was skipped: *out of order* (`out_of_order`); it did
  arrive after all, so it leaves `frames_lost`. The frame is delivered, late.
- d == 0, or -REORDER_WINDOW < d < 0 and the number already arrived: a *duplicate*
  (`duplicates`), dropped.
- anything else (further back, before the segment's first frame, or more than FORWARD_WINDOW
  ahead) is held until the next frame decides: if that one continues from it (seq + 1), a frame
  ahead marks a long outage (a pulled cable at a high rate: the numbers skipped count in
  `frames_lost`, the segment goes on) and one behind a device restart -- a new segment starts
  there (`segments`), nothing counted lost; otherwise it was a *stale* frame (`stale`), dropped
  (one damaged frame with a far sequence number costs nothing). A held frame still undecided at
  the end of the input (`finish`) is stale.
- a hello with seq 0 is the device's restart: a new segment at once.

So `frames_lost` counts only numbers that never arrived, and duplicated, reordered or stale
frames each have their own counter instead of a gap of ~65 535.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Generic, Protocol, TypeVar

import numpy as np
import numpy.typing as npt

REORDER_WINDOW = 128  # frames behind the newest that still count as late, not stale
FORWARD_WINDOW = 4096  # a forward jump up to this is taken at once (~8 s at 500 Hz); a
# longer one waits for the next frame to confirm it

T = TypeVar("T")


class SequenceCounts(Protocol):
    """Where the counters go (framing.DecoderStats)."""

    frames_lost: int
    duplicates: int
    out_of_order: int
    stale: int
    segments: int


@dataclass
class SequenceTracker(Generic[T]):
    """The receiver's state; `accept` appends the items to deliver to `out`."""

    _top: int | None = None  # extended sequence number of the newest frame in the segment
    _first: int = 0  # extended sequence number of the segment's first frame
    _missing: set[int] = field(default_factory=set)  # skipped numbers within the window
    _held: tuple[int, int, T] | None = None  # (seq, distance, frame) out of the window, until
    # the next frame decides

    @property
    def holding(self) -> bool:
        """A frame out of the window waits for the next one to decide what it is."""
        return self._held is not None

    @property
    def last_seq(self) -> int | None:
        """The newest sequence number of the current segment (None before the first)."""
        return None if self._top is None else self._top & 0xFFFF

    def accept(self, seq: int, restart: bool, item: T, st: SequenceCounts, out: list[T]) -> None:
        held = self._held
        if held is not None:
            self._held = None
            h_seq, h_d, h_item = held
            if not restart and seq == (h_seq + 1) & 0xFFFF:
                if h_d > 0 and self._top is not None:  # far ahead, confirmed: an outage
                    st.frames_lost += h_d - 1
                    self._top += h_d
                    self._missing.clear()  # all of them further back than the window
                else:  # behind, confirmed: the device restarted
                    self._segment(h_seq, st)
                out.append(h_item)
            else:
                st.stale += 1
        top = self._top
        if restart or top is None:
            self._segment(seq, st)
            out.append(item)
            return
        d = ((seq - top + 0x8000) & 0xFFFF) - 0x8000
        if d == 1:  # the common case first
            self._top = top + 1
            out.append(item)
            return
        ext = top + d
        if 0 < d <= FORWARD_WINDOW:
            st.frames_lost += d - 1
            self._remember(top + 1, ext)
            self._top = ext
            out.append(item)
        elif -REORDER_WINDOW < d <= 0 and ext >= self._first:
            if ext in self._missing:
                self._missing.discard(ext)
                st.out_of_order += 1
                st.frames_lost -= 1
                out.append(item)
            else:
                st.duplicates += 1
        else:
            self._held = (seq, d, item)

    def finish(self, st: SequenceCounts) -> None:
        """The input ended: a frame still held was stale."""
        if self._held is not None:
            self._held = None
            st.stale += 1

    def _segment(self, seq: int, st: SequenceCounts) -> None:
        st.segments += 1
        self._top = self._first = seq
        self._missing.clear()

    def _remember(self, lo: int, hi: int) -> None:
        """Numbers lo..hi-1 were skipped: remember those still inside the window at hi."""
        lo = max(lo, hi - REORDER_WINDOW + 1)
        if lo < hi:
            if len(self._missing) > 4 * REORDER_WINDOW:
                self._missing = {m for m in self._missing if m > hi - REORDER_WINDOW}
            self._missing.update(range(lo, hi))

    def jump(self, ext_steps: npt.NDArray[np.int64], st: SequenceCounts) -> None:
        """Advance over frames known to be in order (each 1..FORWARD_WINDOW ahead of the one
        before, no restart, nothing held): `ext_steps` are their distances, in order. The
        numbers they skipped are counted lost, those near the end remembered."""
        assert self._top is not None and self._held is None
        if not ext_steps.size:
            return
        top = self._top
        st.frames_lost += int(ext_steps.sum()) - int(ext_steps.size)
        tail = ext_steps[-REORDER_WINDOW:]  # each step advances >= 1: older gaps are out
        base = top + int(ext_steps[: ext_steps.size - tail.size].sum())
        for d in tail.tolist():
            if d > 1:
                self._remember(base + 1, base + d)
            base += d
        self._top = base


def track_bulk(seq: npt.NDArray[np.uint16], restart: npt.NDArray[np.bool_],
               st: SequenceCounts) -> npt.NDArray[np.bool_]:
    """The sequence accounting of SequenceTracker over a whole log, vectorised: which frames are
    delivered (duplicates and stale frames are not). Frames in order (1..FORWARD_WINDOW after
    the frame before, not a restart) are handled in bulk; only the frames around the rest go
    through the tracker one by one. Ends with `finish`."""
    n = int(seq.size)
    keep = np.ones(n, dtype=bool)
    if n == 0:
        return keep
    d = (seq[1:].astype(np.int64) - seq[:-1].astype(np.int64)) & 0xFFFF
    regular = (d >= 1) & (d <= FORWARD_WINDOW)
    regular &= ~restart[1:]
    irregular = np.flatnonzero(~regular) + 1  # frames not simply in order after the one before
    trk: SequenceTracker[int] = SequenceTracker()
    out: list[int] = []  # frames the tracker delivered
    seen: list[int] = []  # frames that went through the tracker
    i = 0
    k_at = 0  # index into `irregular`
    while i < n:
        s_i = int(seq[i])
        trk.accept(s_i, bool(restart[i]), i, st, out)
        seen.append(i)
        i += 1
        if trk.holding or trk.last_seq != s_i:
            continue  # not back in order yet: the next frame goes through the tracker too
        while k_at < irregular.size and irregular[k_at] < i:
            k_at += 1
        k = int(irregular[k_at]) if k_at < irregular.size else n
        if k > i:  # frames i..k-1 follow in order: all delivered
            trk.jump(d[i - 1 : k - 1], st)
            i = k
    trk.finish(st)
    if len(out) < len(seen):
        keep[np.setdiff1d(np.asarray(seen), np.asarray(out, dtype=np.int64))] = False
    return keep
