"""`mirror` resumed from a MirrorState gives exactly the states of one pass (it is how the live
view follows a long filter run), and the live divergence computed refresh by refresh equals the
one computed over the whole run at once."""

from __future__ import annotations

import numpy as np
from fake_device import make_data

from jointangle.bench.accuracy import simulate_seeds
from jointangle.estimators.mirror import (
    MirrorSettings,
    MirrorState,
    quantise_inputs,
    run_mirror,
    step_periods,
)
from jointangle.live.session import DivergenceWorker, FilterRun
from jointangle.rig import parse_rig


def test_mirror_resumed_in_chunks_equals_one_pass() -> None:
    # paper-table2-L10: the omega^2 rows start after 0.25 s (25 steps), inside the second chunk.
    sims, readings = simulate_seeds("paper-table2-L10", range(3))
    cfg = MirrorSettings.from_rig(sims[0].rig)
    acc = quantise_inputs(readings)
    whole, _ = run_mirror(cfg, acc)
    state = MirrorState.fresh(acc.shape[0])
    parts = [run_mirror(cfg, acc[:, a:b], state=state)[0]
             for a, b in [(0, 1), (1, 20), (20, 77), (77, acc.shape[1])]]
    assert state.steps == acc.shape[1]
    np.testing.assert_array_equal(np.concatenate(parts, axis=1), whole)


def test_live_divergence_refresh_by_refresh_equals_one_pass() -> None:
    data, rig_text = make_data(seconds=2.0, perturb_deg=0.01)
    rig = parse_rig(rig_text)
    q24 = data.theta_q24.copy()
    q24[700:] += 1 << 16  # a step in the firmware's θ halfway: max and RMS both move
    # Frame times on the 500 Hz grid, with missed periods (an overrunning board) just before a
    # refresh boundary (frame 300: the chunk's first step predicts over 3 periods) and inside
    # a chunk (frame 600: 2).
    slots = np.arange(len(data.counts))
    slots[300:] += 2
    slots[600:] += 1
    t_us = [int(v) * 2000 for v in slots]
    run = FilterRun(1, (0, 1, 2, 3), list(data.counts), [int(v) for v in q24], t_us)
    whole = DivergenceWorker(rig).compute(run, len(run.counts))
    on_grid = FilterRun(1, (0, 1, 2, 3), list(data.counts), [int(v) for v in q24],
                        [k * 2000 for k in range(len(data.counts))])
    assert DivergenceWorker(rig).compute(on_grid, 800).max_abs_deg != \
        DivergenceWorker(rig).compute(run, 800).max_abs_deg  # the missed periods count
    worker = DivergenceWorker(rig)
    for n in (1, 300, 301, 900, len(run.counts)):
        d = worker.compute(run, n)
    assert d.frames == whole.frames == len(run.counts)
    assert d.max_abs_deg == whole.max_abs_deg
    assert abs(d.rms_deg - whole.rms_deg) < 1e-12 * whole.rms_deg
    assert whole.max_abs_deg > 0.2  # the step is seen
    # A new filter run starts from scratch.
    other = FilterRun(2, (0, 1, 2, 3), list(data.counts[:100]), [int(v) for v in q24[:100]],
                      t_us[:100])
    fresh = DivergenceWorker(rig).compute(other, 100)
    assert worker.compute(other, 100).max_abs_deg == fresh.max_abs_deg


def test_step_periods_as_the_app_counts_them() -> None:
    # firmware/tests/app/test_app_loop.cpp TestStepPeriods, from frame times: round half up, 1..8,
    # uint32 wrap of t_us, the first frame 1.
    gaps = [2000, 0, 2999, 3000, 4000, 6998, 15000, 16000, 2**32 - 1000]
    t = np.cumsum([5000, *gaps]) & 0xFFFFFFFF
    got = step_periods(t.astype(np.uint32), 500)
    assert got.tolist() == [1, 1, 1, 1, 2, 2, 3, 8, 8, 8]
    wrap_t = np.array([2**32 - 1000, 1000], dtype=np.uint32)  # 2000 µs across the wrap
    assert step_periods(wrap_t, 500).tolist() == [1, 1]
    assert step_periods(np.array([0, 9999], dtype=np.uint32), 300).tolist() == [1, 3]


def test_mirror_predicts_over_missed_periods() -> None:
    sims, readings = simulate_seeds("paper-table2-L10", range(1))
    readings = readings[:, :400]
    cfg = MirrorSettings.from_rig(sims[0].rig)
    acc = quantise_inputs(readings)
    T = acc.shape[1]
    ones, _ = run_mirror(cfg, acc, periods=np.ones(T, dtype=np.int64))
    plain, _ = run_mirror(cfg, acc)
    np.testing.assert_array_equal(ones, plain)
    periods = np.ones(T, dtype=np.int64)
    periods[200] = 3
    gapped, _ = run_mirror(cfg, acc, periods=periods)
    np.testing.assert_array_equal(gapped[:, :200], plain[:, :200])
    assert not np.array_equal(gapped[:, 200], plain[:, 200])
    # Step 200 over three periods = two extra time updates with its readings, then step 200.
    state = MirrorState.fresh(1)
    run_mirror(cfg, acc[:, :200], state=state)
    extra = np.ones(1, dtype=np.int64) * 3
    by_parts, _ = run_mirror(cfg, acc[:, 200:201], state=state, periods=extra)
    np.testing.assert_array_equal(by_parts[:, 0], gapped[:, 200])
