import sys, json; sys.path.insert(0, __import__("os").path.dirname(__import__("os").path.abspath(__file__)))
from study import *
REC2 = {"l": True, "sincos": "q0.16sm", "k": "vec", "inv": True, "h": "split", "h_ang": False}
REC = {"l": True, "inv": True, "k": "vec", "angsc": True, "h": "split", "g": True, "sincos": "q0.16sm"}
out = {}
for suffix in ("", "@s20", "@gen"):
    SC = [s + suffix for s in scenario_names()]
    for name, opt, st in [("REC2 (cost-effective set)", REC2, ("row", "u", "filter")),
                          ("REC2, settings both", REC2, ("row", "u", "both")),
                          ("REC2 without l (increment only)", {**REC2, "l": False}, ("row", "u", "filter")),
                          ("REC (all, incl. b'', angle-row h, g) + dt", REC, ("row", "u", "filter"))]:
        if suffix and name.startswith("REC (all"): continue
        r = run_candidate(name, opt, 20, st, scen=SC)
        print(suffix or "@s0", fmt(r))
        print("     ", {k.split("@")[0].replace("paper-table2-", "").replace("gravity-", "g-"): (round(v["max"], 5), round(v["rms"], 5), round(v["dw"], 4)) for k, v in r["per"].items()}, flush=True)
        out[(suffix or "@s0") + " " + name] = r
json.dump(out, open("/tmp/numstudy/results_rec2.json", "w"), indent=1, default=str)
