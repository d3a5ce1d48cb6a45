import sys, time, json; sys.path.insert(0, __import__("os").path.dirname(__import__("os").path.abspath(__file__)))
from study import *
NS = int(sys.argv[1]) if len(sys.argv) > 1 else 20
C = [
 ("(0) l Q5.10 [firmware today]", {"l": True}, None),
 ("(a) sin/cos Q1.14", {"sincos": "q1.14"}, None),
 ("(a') sin/cos Q0.15", {"sincos": "q0.15"}, None),
 ("(a'') sin/cos Q1.14 + c2s2 Q1.14", {"sincos": "q1.14", "c2s2": True}, None),
 ("(b) k, 1 exp/update", {"k": "vec"}, None),
 ("(b') k, 1 exp/entry", {"k": "entry"}, None),
 ("(b'') angle nu/s, D0/s mant16", {"angsc": True}, None),
 ("(c) 1/s, 1/D mant16", {"inv": True}, None),
 ("(d) h~ 1 exp/row", {"h": "row"}, None),
 ("(d') h~ 1 exp/entry", {"h": "entry"}, None),
 ("(d'') h~ Q6.9 [rejected]", {"h": "q6.9"}, None),
 ("(d+) g mant16", {"g": True}, None),
 ("(e) G,F row-exp, both", {}, ("row", False, "both")),
 ("(e) G,F row-exp, filter only", {}, ("row", False, "filter")),
 ("(e') G,F matrix-exp, filter only", {}, ("mat", False, "filter")),
 ("(e'') G,F link-exp, filter only", {}, ("link", False, "filter")),
 ("(e''') G,F link-exp, both", {}, ("link", False, "both")),
 ("(g) dt mant16, filter only", {}, (None, True, "filter")),
 ("(f) P 1 exp/matrix", {"P": "matrix"}, None),
 ("(f') P diag/offdiag exps", {"P": "diagoff"}, None),
 ("(f'') P 1 exp/entry", {"P": "entry"}, None),
]
res = []
for name, opt, st in C:
    t0 = time.time()
    r = run_candidate(name, opt, NS, st)
    res.append(r)
    print(fmt(r), f"[{time.time()-t0:.0f}s]", flush=True)
json.dump(res, open(f"/tmp/numstudy/results_single_{NS}.json", "w"), indent=1, default=str)
