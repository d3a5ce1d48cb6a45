"""Inputs for seeds 20-39 (scenario rigs) and for general_rig (seeds 0-19), as parity.py builds them."""
import pickle, time
import numpy as np
from jointangle.bench.accuracy import simulate_seeds
from jointangle.bench.parity import general_rig
from jointangle.estimators.base import sensor_to_link
from jointangle.estimators.mirror import quantise_inputs
from jointangle.sim.scenarios import scenario_names, simulate
for sc in scenario_names():
    t0 = time.time()
    sims, acc = simulate_seeds(sc, list(range(20, 40)))
    np.savez(f"/tmp/numstudy/inputs/{sc}@s20.npz", acc=acc, accq=quantise_inputs(acc), t=sims[0].t)
    pickle.dump(sims[0].rig, open(f"/tmp/numstudy/inputs/{sc}@s20.rig.pkl", "wb"))
    rig = general_rig(sims[0].rig)
    runs = [simulate(sc, seed=s, rate_hz=rig.sample_rate_hz, rig=rig) for s in range(20)]
    acc = np.stack([sensor_to_link(rig, r.readings) for r in runs])
    np.savez(f"/tmp/numstudy/inputs/{sc}@gen.npz", acc=acc, accq=quantise_inputs(acc), t=runs[0].t)
    pickle.dump(rig, open(f"/tmp/numstudy/inputs/{sc}@gen.rig.pkl", "wb"))
    print(sc, f"{time.time()-t0:.1f}s", flush=True)
