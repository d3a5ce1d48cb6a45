"""Estimators fed as the samples arrive (`live`, `record`): push readings, get the estimates
that are now final.

The estimators (base.py) run on a whole run at once. A `StreamingEstimator` takes the same
link-frame readings in chunks — `push(acc)` with acc (S, B, M), B ≥ 0 new samples — and returns
the estimates (S, K) of the next K samples whose estimate will not change any more: every
sample at once for a causal filter, all but the newest `lag_samples` for a fixed-lag smoother.
`finish()` returns the rest, as the batch run ends its data. Pushed in any chunks, the
estimates are the batch run's (`tests/host/estimators/test_streaming.py`: np.allclose).

- `array-ekf`: the forward pass continued from where the last push stopped (`FilterState`).
- `array-fls`: the same forward pass, which keeps the history the smoother needs from the
  oldest sample not yet final on; each push smooths that window (`fixed_lag`) and hands out
  the samples whose lag has passed. The first output needs the first lag + 1 samples (the
  batch run initialises from them too).
- `analytical`, `smooth`: finite memory; each push reruns the batch estimate over the new
  samples and the few before them that the window reaches.

Other filters (the paper's, `mirror`, the offline and gyro methods) carry a state the batch
code does not hand out, or need the whole run: `streaming_estimator` refuses them by name.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np

from jointangle.errors import InputError
from jointangle.estimators.analytical import SMOOTH_WINDOW, Analytical, SmoothAnalytical
from jointangle.estimators.array_kf import (
    DEFAULT_Q_ALPHA,
    DEFAULT_Q_JOINT,
    FLS_LAG_S,
    FilterState,
    ForwardPass,
    _estimates,
    _pick,
    fixed_lag,
    forward,
)
from jointangle.estimators.base import Estimates, Estimator
from jointangle.rig import Rig


class StreamingEstimator(Protocol):
    name: str

    @property
    def lag_samples(self) -> int:
        """How many samples after its own an estimate waits for (0: causal)."""
        ...

    def push(self, acc: np.ndarray) -> Estimates:
        """Take the next samples acc (S, B, M); the estimates (S, K) of the samples that are
        now final, in order, continuing from the last call's."""
        ...

    def finish(self) -> Estimates:
        """No more samples: the estimates of every sample not handed out yet (the last ones
        with the shorter windows the batch run gives the end of its data)."""
        ...


def empty_estimates(S: int) -> Estimates:
    e = np.zeros((S, 0))
    return Estimates(e, e.copy(), e.copy(), e.copy())


def concat_estimates(parts: list[Estimates], S: int) -> Estimates:
    """Estimates (S, ΣK) of parts in order; theta_sigma only when every part has it."""
    if not parts:
        return empty_estimates(S)
    sig = [p.theta_sigma for p in parts]
    return Estimates(np.concatenate([p.theta for p in parts], axis=1),
                     np.concatenate([p.omega_a for p in parts], axis=1),
                     np.concatenate([p.omega_b for p in parts], axis=1),
                     None if any(s is None for s in sig)
                     else np.concatenate([s for s in sig if s is not None], axis=1))


class ArrayEKFStream:
    """`array-ekf` sample by sample: the hypothesis bank's forward pass, continued per push."""

    name = "array-ekf"
    lag_samples = 0

    def __init__(self, rig: Rig, q_alpha: float = DEFAULT_Q_ALPHA,
                 q_joint: float = DEFAULT_Q_JOINT) -> None:
        self.rig = rig
        self.q_alpha = q_alpha
        self.q_joint = q_joint
        self._state: FilterState | None = None
        self._done = 0

    def push(self, acc: np.ndarray) -> Estimates:
        if acc.shape[1] == 0:
            return empty_estimates(acc.shape[0])
        fw = forward(self.rig, acc, self.q_alpha, self.q_joint, keep_history=False,
                     start=self._state, offset=self._done)
        self._state = fw.final
        self._done += acc.shape[1]
        best = np.argmax(fw.loglik, axis=1)  # the member reported at each step (causal)
        return _estimates(_pick(fw.x, best), _pick(fw.theta_var, best))

    def finish(self) -> Estimates:
        S = 1 if self._state is None else self._state.x.shape[0]
        return empty_estimates(S)


class _History:
    """The forward pass's per-sample arrays from the oldest sample not yet final on."""

    def __init__(self) -> None:
        self.parts: list[ForwardPass] = []

    def append(self, fw: ForwardPass) -> None:
        self.parts.append(fw)

    def joined(self) -> ForwardPass:
        """One ForwardPass over every sample held (history included)."""
        if len(self.parts) > 1:
            ps = self.parts

            def cat(get: Callable[[ForwardPass], np.ndarray | None]) -> np.ndarray:
                arrs = [get(p) for p in ps]
                return np.concatenate([a for a in arrs if a is not None], axis=2)

            self.parts = [ForwardPass(
                x=cat(lambda p: p.x), theta_var=cat(lambda p: p.theta_var),
                loglik=cat(lambda p: p.loglik), Phi=ps[-1].Phi, final=ps[-1].final,
                x_pred=cat(lambda p: p.x_pred), P_pred=cat(lambda p: p.P_pred),
                P=cat(lambda p: p.P))]
        return self.parts[0]

    def drop(self, n: int) -> None:
        """Forget the first n samples held."""
        fw = self.joined()
        xp, Pp, P = fw.history()
        self.parts = [ForwardPass(x=fw.x[:, :, n:], theta_var=fw.theta_var[:, :, n:],
                                  loglik=fw.loglik[:, :, n:], Phi=fw.Phi, final=fw.final,
                                  x_pred=xp[:, :, n:], P_pred=Pp[:, :, n:], P=P[:, :, n:])]


class ArrayFLSStream:
    """`array-fls` as the samples arrive: estimates `lag_samples` (100 ms) behind the newest."""

    name = "array-fls"

    def __init__(self, rig: Rig, q_alpha: float = DEFAULT_Q_ALPHA,
                 q_joint: float = DEFAULT_Q_JOINT, lag_s: float = FLS_LAG_S) -> None:
        self.rig = rig
        self.q_alpha = q_alpha
        self.q_joint = q_joint
        self._lag = int(np.floor(lag_s * rig.sample_rate_hz + 1e-9))
        self._waiting: np.ndarray | None = None  # samples before the first forward pass
        self._hist = _History()
        self._held = 0  # samples in the history, none of them handed out yet
        self._seen = 0  # samples run through the forward pass

    @property
    def lag_samples(self) -> int:
        return self._lag

    def _run(self, acc: np.ndarray) -> None:
        start = None if self._seen == 0 else self._hist.joined().final
        fw = forward(self.rig, acc, self.q_alpha, self.q_joint, keep_history=True,
                     init_window=self._lag + 1, start=start, offset=self._seen)
        self._hist.append(fw)
        self._held += acc.shape[1]
        self._seen += acc.shape[1]

    def _take(self, n: int) -> Estimates:
        """Smooth the history and hand out its first n samples' estimates."""
        x, v = fixed_lag(self._hist.joined(), self._lag)
        self._hist.drop(n)
        self._held -= n
        return _estimates(x[:, :n], v[:, :n])

    def push(self, acc: np.ndarray) -> Estimates:
        S = acc.shape[0]
        if self._seen == 0:  # the first forward pass starts from the first lag + 1 samples
            acc = acc if self._waiting is None else np.concatenate([self._waiting, acc], 1)
            if acc.shape[1] < self._lag + 1:
                self._waiting = acc
                return empty_estimates(S)
            self._waiting = None
        if acc.shape[1]:
            self._run(acc)
        final = self._held - self._lag  # these have seen their lag samples
        return self._take(final) if final > 0 else empty_estimates(S)

    def finish(self) -> Estimates:
        if self._waiting is not None:  # fewer than lag + 1 samples in all: start from them
            acc, self._waiting = self._waiting, None
            self._run(acc)
        if self._held == 0:
            return empty_estimates(1 if self._seen == 0 else self._hist.joined().x.shape[0])
        return self._take(self._held)


class WindowedStream:
    """An estimator whose output at sample k depends on samples k − before … k + after only:
    each push reruns it over the new samples and the `before + after` held back before them."""

    def __init__(self, est: Estimator, rig: Rig, before: int, after: int) -> None:
        self.name = est.name
        self.est = est
        self.rig = rig
        self.before = before
        self.after = after
        self._buf: np.ndarray | None = None  # the samples the next outputs' windows reach
        self._lead = 0  # of them, how many precede the first sample not handed out yet

    @property
    def lag_samples(self) -> int:
        return self.after

    def _estimate(self, upto: int) -> Estimates:
        assert self._buf is not None
        e = self.est.estimate(self.rig, self._buf)
        sl = slice(self._lead, upto)
        return Estimates(e.theta[:, sl], e.omega_a[:, sl], e.omega_b[:, sl],
                         None if e.theta_sigma is None else e.theta_sigma[:, sl])

    def push(self, acc: np.ndarray) -> Estimates:
        S = acc.shape[0]
        self._buf = acc if self._buf is None else np.concatenate([self._buf, acc], axis=1)
        T = self._buf.shape[1]
        upto = T - self.after  # the samples before it have all of their window
        if upto <= self._lead:
            return empty_estimates(S)
        out = self._estimate(upto)
        keep = max(upto - self.before, 0)
        self._buf = self._buf[:, keep:]
        self._lead = upto - keep
        return out

    def finish(self) -> Estimates:
        if self._buf is None or self._buf.shape[1] <= self._lead:
            return empty_estimates(1 if self._buf is None else self._buf.shape[0])
        out = self._estimate(self._buf.shape[1])
        self._buf, self._lead = None, 0
        return out


STREAMING: dict[str, Callable[[Rig], StreamingEstimator]] = {
    "array-ekf": ArrayEKFStream,
    "array-fls": ArrayFLSStream,
    "analytical": lambda rig: WindowedStream(Analytical(), rig, 0, 0),
    "smooth": lambda rig: WindowedStream(SmoothAnalytical(), rig, (SMOOTH_WINDOW - 1) // 2,
                                         (SMOOTH_WINDOW - 1) // 2),
}


def streaming_estimator(name: str, rig: Rig, field: str = "--host-filter"
                        ) -> StreamingEstimator:
    """The streaming form of estimator `name` on `rig`; InputError naming the ones there are
    when it has none."""
    try:
        factory = STREAMING[name]
    except KeyError:
        raise InputError(f"filter {name!r} cannot run on samples as they arrive (it needs the "
                         "whole run, or gyro rates); choose one of "
                         f"{', '.join(STREAMING)} or none", field=field) from None
    return factory(rig)
