"""`mirror` resumed from a MirrorState gives exactly the states of one pass (it is how the live
view follows a long filter run), and the live divergence computed refresh by refresh equals the
one computed over the whole run at once."""

from __future__ import annotations

import numpy as np
from fake_device import make_data

from jointangle.bench.accuracy import simulate_seeds
from jointangle.estimators.mirror import MirrorSettings, MirrorState, quantise_inputs, run_mirror
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
    run = FilterRun(1, (0, 1, 2, 3), list(data.counts), [int(v) for v in q24])
    whole = DivergenceWorker(rig).compute(run, len(run.counts))
    worker = DivergenceWorker(rig)
    for n in (1, 300, 301, 900, len(run.counts)):
        d = worker.compute(run, n)
    assert d.frames == whole.frames == len(run.counts)
    assert d.max_abs_deg == whole.max_abs_deg
    assert abs(d.rms_deg - whole.rms_deg) < 1e-12 * whole.rms_deg
    assert whole.max_abs_deg > 0.2  # the step is seen
    # A new filter run starts from scratch.
    other = FilterRun(2, (0, 1, 2, 3), list(data.counts[:100]), [int(v) for v in q24[:100]])
    fresh = DivergenceWorker(rig).compute(other, 100)
    assert worker.compute(other, 100).max_abs_deg == fresh.max_abs_deg
