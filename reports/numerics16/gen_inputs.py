"""Cache the parity bench's inputs (simulate_seeds + quantise_inputs) per scenario."""
import sys, time
import numpy as np
from jointangle.bench.accuracy import simulate_seeds
from jointangle.sim.scenarios import scenario_names
from jointangle.estimators.mirror import quantise_inputs
seeds = range(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
for sc in scenario_names():
    t0 = time.time()
    sims, acc = simulate_seeds(sc, list(seeds))
    np.savez(f"/tmp/numstudy/inputs/{sc}.npz", acc=acc, accq=quantise_inputs(acc), t=sims[0].t)
    import pickle
    with open(f"/tmp/numstudy/inputs/{sc}.rig.pkl", "wb") as f:
        pickle.dump(sims[0].rig, f)
    print(sc, acc.shape, sims[0].rig.dt, f"{time.time()-t0:.1f}s", flush=True)
