"""Run quantised-mirror candidates against the unmodified mirror on the parity bench's inputs."""
import json, pickle, sys, time
import numpy as np
sys.path.insert(0, __import__("os").path.dirname(__import__("os").path.abspath(__file__)))
import quant_mirror as qm
from jointangle.estimators.base import wrap
from jointangle.estimators.mirror import MirrorSettings, run_mirror
from jointangle.sim.scenarios import scenario_names

SCEN = scenario_names()
_ref = {}

def load(sc, nseeds):
    d = np.load(f"/tmp/numstudy/inputs/{sc}.npz")
    with open(f"/tmp/numstudy/inputs/{sc}.rig.pkl", "rb") as f:
        rig = pickle.load(f)
    return rig, d["accq"][:nseeds], d["t"]

def metrics(xq, xm, t):
    dth = np.degrees(np.abs(wrap(xq[..., 2] - xm[..., 2])))
    dw = np.degrees(np.maximum(np.abs(xq[..., 0] - xm[..., 0]), np.abs(xq[..., 1] - xm[..., 1])))
    late = t >= 2.0
    return dict(max=float(dth[:, late].max()),
                rms=float(np.sqrt(np.mean(dth[:, late] ** 2, axis=1)).max()),
                dw=float(dw[:, late].max()), early=float(dth[:, ~late].max()))

def run_candidate(name, opt, nseeds=10, settings=None, scen=None):
    """settings: None | (gf, dt16, mode) with mode 'both' or 'filter'."""
    out = {}
    for sc in scen or SCEN:
        rig, acc, t = load(sc, nseeds)
        cfg = MirrorSettings.from_rig(rig)
        cfg_f = cfg
        key = (sc, nseeds)
        if settings:
            gf, dt16, mode = settings
            cfg_f = qm.quantise_settings(cfg, rig, gf, dt16)
            if mode == "both":
                key = (sc, nseeds, gf, dt16)
                if key not in _ref:
                    _ref[key] = run_mirror(cfg_f, acc)[0]
        if key not in _ref:
            _ref[key] = run_mirror(cfg, acc)[0]
        qm.STATS.clear()
        xq = qm.run_quant(cfg_f, acc, opt)
        m = metrics(xq, _ref[key], t)
        m["stats"] = {k: v for k, v in qm.STATS.items()}
        out[sc] = m
    worst = {k: max(out[s][k] for s in out) for k in ("max", "rms", "dw", "early")}
    wsc = {k: max(out, key=lambda s: out[s][k]) for k in ("max", "rms", "dw")}
    return dict(name=name, opt=opt, settings=settings, nseeds=nseeds, per=out, worst=worst,
                worst_scen=wsc)

def fmt(r):
    w, ws = r["worst"], r["worst_scen"]
    st = {}
    for s in r["per"].values():
        for k, v in s["stats"].items():
            if k.startswith("min_eig"):
                st[k] = min(st.get(k, np.inf), v)
            else:
                st[k] = st.get(k, 0) + v
    return (f"{r['name']:<34} max {w['max']:.5f} ({ws['max'][:14]})  rms {w['rms']:.6f} "
            f"({ws['rms'][:14]})  dw {w['dw']:.4f} ({ws['dw'][:14]})  early {w['early']:.4f}  "
            + " ".join(f"{k}={v:.2g}" if isinstance(v, float) else f"{k}={v}" for k, v in st.items()))
