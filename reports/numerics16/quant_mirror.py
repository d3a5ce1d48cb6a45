"""A copy of jointangle.estimators.mirror.run_mirror with hooks that quantise chosen
intermediate quantities to 16-bit representations (numerical design study, /tmp/numstudy).

Quantisers (all round half up, saturating):
  fixq(x, F)      : fixed 16-bit Q(15-F).F  (int16 raw in [-32768, 32767])
  mant(X)         : 16-bit signed mantissa with ONE power-of-two exponent shared by the last axis
                    of X (per seed): e = floor(log2 max|X|) + 1, lsb = 2^(e-15), so the largest
                    entry has a mantissa magnitude in [16384, 32767] (15 bits + sign).

Options (dict `opt`; absent / None = float64 exactly as mirror.py):
  sincos : 'q1.14' | 'q0.15'     c, s of theta (h = R u, R'u, R c_b, cos2/sin2 all use them)
  c2s2   : True                  cos 2θ, sin 2θ also Q1.14 (only used when M_b != m I)
  l      : True                  decorrelation factors l as Q5.10 (the firmware's Fixed16 Factor)
  inv    : True                  1/D0, 1/D1, 1/D2 and every update's 1/s as 16-bit mantissas
  k      : 'vec' | 'entry'       Kalman gains: k0,k1 of the angle rows (one exponent per
                                 update) and k of z~1, z~2 (one exponent per update); 'entry' =
                                 one exponent per entry
  angsc  : True                  angle-row scalars nu/s and D0/s as 16-bit mantissas
  h      : 'row' | 'entry' | 'q6.9'
                                 H~ rows: angle rows c1 (=R'u_1), c2 (=h~ of z~4) and
                                 c2w = rho*c2 each a 16-bit mantissa; rows z~1, z~2 as a
                                 16-bit mantissa vector with one exponent per row ('row'),
                                 per entry ('entry'), or fixed Q6.9 (the rejected design)
  h_ang  : False                 with h: leave the angle rows' c1, c2, c2w in float (32-bit)
  g      : True                  the angle rows' information sum g as a 16-bit mantissa
  P      : 'matrix' | 'entry' | 'diagoff'
                                 P stored as 16-bit mantissas after every (sub)update: one
                                 exponent for the matrix / per entry / one for the diagonal and
                                 one for the off-diagonal
Settings quantisation (G, F, dt) is applied to a MirrorSettings by quantise_settings() and
then given to this filter and, for the "both" mode, to the unmodified run_mirror as well.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from jointangle.estimators.base import full_noise_variance, wrap
from jointangle.estimators.mirror import (
    INIT_MIN_PRODUCT, P_OMEGA0, P_THETA0, MirrorSettings, hold_steps)

STATS: dict[str, int] = {}


def _count(name: str, n: int) -> None:
    if n:
        STATS[name] = STATS.get(name, 0) + int(n)


def fixq(x, frac, name="fix"):
    raw = np.floor(np.asarray(x, dtype=float) * 2.0**frac + 0.5)
    _count("sat:" + name, np.count_nonzero((raw > 32767) | (raw < -32768)))
    return np.clip(raw, -32768, 32767) / 2.0**frac


def mant(X, name="mant"):
    """16-bit mantissa, one exponent over the last axis (per leading index)."""
    X = np.asarray(X, dtype=float)
    m = np.max(np.abs(X), axis=-1, keepdims=True)
    with np.errstate(divide="ignore"):
        e = np.where(m > 0, np.floor(np.log2(np.where(m > 0, m, 1.0))) + 1.0, 0.0)
    lsb = 2.0 ** (e - 15.0)
    raw = np.floor(X / lsb + 0.5)
    _count("clip:" + name, np.count_nonzero(raw > 32767))
    return np.clip(raw, -32768, 32767) * lsb


def mant1(x, name="mant1"):
    """A scalar per seed (S,) as a 16-bit mantissa with its own exponent."""
    return mant(np.asarray(x)[:, None], name)[:, 0]


def mant_vec(name, *xs):
    """Several (S,) arrays sharing one exponent per seed."""
    X = mant(np.stack(xs, axis=-1), name)
    return [X[:, i] for i in range(len(xs))]


def quantise_settings(cfg: MirrorSettings, rig, gf: str | None = None, dt16: bool = False
                      ) -> MirrorSettings:
    """G, F (and ΔT) rounded to 16-bit mantissas; the derived noise constants recomputed from
    the rounded coefficients (as Configure would from what it stores).
    gf = 'row': one exponent per coefficient row (F row 0, F row 1, G_w2, ΔT G_α per link);
    gf = 'mat': one per matrix (F, G_w2, ΔT G_α per link); gf = 'link': one per link for all."""
    dt = cfg.dt
    if dt16 == "u":  # unsigned 16-bit mantissa (ΔT > 0): leading bit at 2^15
        e = np.floor(np.log2(dt)) + 1.0
        dt = float(np.floor(dt * 2.0 ** (16 - e) + 0.5) * 2.0 ** (e - 16))
    elif dt16:
        dt = float(mant(np.array([[dt]]))[0, 0])
    def link(gw2, gal, f):
        dgal = cfg.dt * gal  # the firmware stores ΔT G_α (DtCoef)
        if gf == "row":
            gw2q = mant(gw2[None])[0]
            dgalq = mant(dgal[None])[0]
            fq = mant(f)
        elif gf == "mat":
            gw2q = mant(gw2[None])[0]
            dgalq = mant(dgal[None])[0]
            fq = mant(f.reshape(1, -1)).reshape(f.shape)
        elif gf == "link":
            allc = np.concatenate([gw2, dgal, f.ravel()])
            q = mant(allc[None])[0]
            n = gw2.size
            gw2q, dgalq, fq = q[:n], q[n:2 * n], q[2 * n:].reshape(f.shape)
        else:
            gw2q, dgalq, fq = gw2, dgal, f
        return gw2q, dgalq / dt, fq
    gw2a, gala, fa = link(cfg.g_w2_a, cfg.g_al_a, cfg.f_a)
    gw2b, galb, fb = link(cfg.g_w2_b, cfg.g_al_b, cfg.f_b)
    q = full_noise_variance(rig)
    na = gw2a.shape[0]
    qa, qb = q[:na], q[na:]
    return replace(
        cfg, dt=dt, g_w2_a=gw2a, g_al_a=gala, f_a=fa, g_w2_b=gw2b, g_al_b=galb, f_b=fb,
        q_a=dt**2 * float(np.sum(gala**2 * qa)), q_b=dt**2 * float(np.sum(galb**2 * qb)),
        r11=float(np.sum(gw2a**2 * qa)), r22=float(np.sum(gw2b**2 * qb)),
        r13=(fa * qa) @ gw2a, c_b=(fb * qb) @ gw2b, m_a=(fa * qa) @ fa.T,
        m_b=(fb * qb) @ fb.T)


def _qP(P, mode):
    if not mode:
        return P
    S = P.shape[0]
    iu = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    v = np.stack([P[:, i, j] for i, j in iu], axis=-1)
    if mode == "matrix":
        v = mant(v, "P")
    elif mode == "entry":
        v = mant(v[..., None], "P")[..., 0]
    elif mode == "diagoff":
        d = mant(v[:, [0, 3, 5]], "Pd")
        o = mant(v[:, [1, 2, 4]], "Po")
        v = np.stack([d[:, 0], o[:, 0], o[:, 1], d[:, 1], o[:, 2], d[:, 2]], axis=-1)
    Q = np.empty_like(P)
    for n, (i, j) in enumerate(iu):
        Q[:, i, j] = v[:, n]
        Q[:, j, i] = v[:, n]
    return Q


def run_quant(cfg: MirrorSettings, acc: np.ndarray, opt: dict | None = None,
              stats: dict | None = None) -> np.ndarray:
    """run_mirror's step with quantisation hooks; returns states (S, T, 3)."""
    opt = opt or {}
    S, T, _ = acc.shape
    na = cfg.g_w2_a.shape[0]
    dt = cfg.dt
    x = np.zeros((S, 3))
    P = np.zeros((S, 3, 3))
    xs = np.empty((S, T, 3))
    skipped = np.zeros(S, dtype=int)
    hold = hold_steps(dt)
    sc_mode = opt.get("sincos")
    kmode = opt.get("k")
    hmode = opt.get("h")
    pmode = opt.get("P")
    # ΔT G_α as the firmware stores it (DtCoef); dt * (a @ g_al) in mirror, (a @ (dt g_al)) here
    # only when the settings were quantised (otherwise keep mirror's exact operation order).
    dgal = opt.get("_dgal")
    minP22 = np.inf
    for k in range(T):
        aa, ab = acc[:, k, :na], acc[:, k, na:]
        za = aa @ cfg.f_a.T
        u = ab @ cfg.f_b.T
        cross = za[:, 0] * u[:, 1] - za[:, 1] * u[:, 0]
        dot = za[:, 0] * u[:, 0] + za[:, 1] * u[:, 1]
        theta_an = np.arctan2(cross, dot)
        if k == 0:
            ok = cross**2 + dot**2 >= INIT_MIN_PRODUCT**2
            x[:, 2] = np.where(ok, theta_an, 0.0)
            P[:, 0, 0] = P_OMEGA0
            P[:, 1, 1] = P_OMEGA0
            P[:, 2, 2] = np.where(ok, P_THETA0, 1.0)
            P = _qP(P, pmode)
        # 1. Time update.
        x[:, 2] = wrap(x[:, 2] + dt * (x[:, 0] - x[:, 1]))
        if dgal is None:
            x[:, 0] = x[:, 0] + dt * (aa @ cfg.g_al_a)
            x[:, 1] = x[:, 1] + dt * (ab @ cfg.g_al_b)
        else:
            x[:, 0] = x[:, 0] + aa @ dgal[0]
            x[:, 1] = x[:, 1] + ab @ dgal[1]
        w = P[:, :, 0] - P[:, :, 1]
        dt_dw = dt * w[:, 0] - dt * w[:, 1]
        p22 = P[:, 2, 2] + dt * w[:, 2] + dt * w[:, 2] + dt * dt_dw
        p02 = P[:, 0, 2] + dt * w[:, 0]
        p12 = P[:, 1, 2] + dt * w[:, 1]
        P[:, 2, 2] = p22
        P[:, 0, 2] = P[:, 2, 0] = p02
        P[:, 1, 2] = P[:, 2, 1] = p12
        P[:, 0, 0] += cfg.q_a
        P[:, 1, 1] += cfg.q_b
        P = _qP(P, pmode)
        # 2. Measurement at x⁻.
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        if sc_mode == "q1.14":
            c, s = fixq(c, 14, "cs"), fixq(s, 14, "cs")
        elif sc_mode == "q0.15":
            c = np.clip(fixq(c, 15, "cs_"), -32767 / 32768, 32767 / 32768)
            s = np.clip(fixq(s, 15, "cs_"), -32767 / 32768, 32767 / 32768)
        elif sc_mode == "q0.16sm":  # sign + unsigned 16-bit magnitude
            c = np.sign(c) * np.minimum(np.floor(np.abs(c) * 65536 + 0.5), 65535) / 65536
            s = np.sign(s) * np.minimum(np.floor(np.abs(s) * 65536 + 0.5), 65535) / 65536
        h3 = c * u[:, 0] + s * u[:, 1]
        h4 = c * u[:, 1] - s * u[:, 0]
        j3, j4 = h4, -h3
        y1 = aa @ cfg.g_w2_a - x[:, 0] * x[:, 0]
        y2 = ab @ cfg.g_w2_b - x[:, 1] * x[:, 1]
        y3 = za[:, 0] - h3
        y4 = za[:, 1] - h4
        c2 = c * c - s * s
        sc = s * c
        s2 = sc + sc
        if opt.get("c2s2"):
            c2, s2 = fixq(c2, 14, "c2"), fixq(s2, 14, "c2")
        e = cfg.mb_dif * c2 + cfg.m_b[0, 1] * s2
        R33 = cfg.r33_0 + e
        R44 = cfg.r44_0 - e
        R34 = cfg.m_a[0, 1] + cfg.m_b[0, 1] * c2 - cfg.mb_dif * s2
        R13, R14 = cfg.r13[0], cfg.r13[1]
        R23 = -(c * cfg.c_b[0] + s * cfg.c_b[1])
        R24 = -(c * cfg.c_b[1] - s * cfg.c_b[0])
        # 3. Decorrelation.
        zero = np.zeros(S)
        ql = (lambda v: fixq(v, 10, "l")) if opt.get("l") else (lambda v: v)
        qi = (lambda v: mant1(np.broadcast_to(v, (S,)).astype(float), "inv")) \
            if opt.get("inv") else (lambda v: v)
        d0 = R33
        i0 = qi(1.0 / d0)
        l10 = ql(R34 * i0)
        d1 = R44 - l10 * R34
        i1 = qi(1.0 / d1)
        yt1 = y4 - l10 * y3
        ht1 = j4 - l10 * j3
        R14t = R14 - l10 * R13
        R24t = R24 - l10 * R23
        l20 = ql(R13 * i0)
        l21 = ql(R14t * i1)
        d2 = cfg.r11 - l20 * R13 - l21 * R14t
        i2 = qi(1.0 / d2)
        yt2 = y1 - l20 * y3 - l21 * yt1
        ht2_0 = 2.0 * x[:, 0]
        ht2_2 = -(l20 * j3 + l21 * ht1)
        R21t = -(l20 * R23 + l21 * R24t)
        l30 = ql(R23 * i0)
        l31 = ql(R24t * i1)
        l32 = ql(R21t * i2)
        d3 = cfg.r22 - l30 * R23 - l31 * R24t - l32 * R21t
        yt3 = y2 - l30 * y3 - l31 * yt1 - l32 * yt2
        ht3_0 = -(l32 * ht2_0)
        ht3_1 = 2.0 * x[:, 1]
        ht3_2 = -(l30 * j3 + l31 * ht1 + l32 * ht2_2)
        # H~ rows as 16-bit values
        if hmode == "row":
            ht2_0, ht2_2 = mant_vec("h", ht2_0, ht2_2)
            ht3_0, ht3_1, ht3_2 = mant_vec("h", ht3_0, ht3_1, ht3_2)
        elif hmode == "row1":  # z~1 one exponent, z~2 per entry
            ht2_0, ht2_2 = mant_vec("h", ht2_0, ht2_2)
            ht3_0, ht3_1, ht3_2 = (mant1(v, "h") for v in (ht3_0, ht3_1, ht3_2))
        elif hmode == "row2":  # z~2 one exponent, z~1 per entry
            ht2_0, ht2_2 = (mant1(v, "h") for v in (ht2_0, ht2_2))
            ht3_0, ht3_1, ht3_2 = mant_vec("h", ht3_0, ht3_1, ht3_2)
        elif hmode == "split":  # omega entries of a row share one exponent, theta entry its own
            ht2_0, ht2_2 = mant1(ht2_0, "h"), mant1(ht2_2, "h")
            ht3_0, ht3_1 = mant_vec("h", ht3_0, ht3_1)
            ht3_2 = mant1(ht3_2, "h")
        elif hmode in ("fixw", "fixw11"):  # 2w entries fixed Q3.12 (or Q4.11), others own exponent
            fb = 12 if hmode == "fixw" else 11
            ht2_0, ht3_1 = fixq(ht2_0, fb, "hw"), fixq(ht3_1, fb, "hw")
            ht3_0 = mant1(ht3_0, "h")
            ht2_2, ht3_2 = mant1(ht2_2, "h"), mant1(ht3_2, "h")
        elif hmode == "th":  # only the theta entries (own exponent each); omega entries 32-bit
            ht2_2, ht3_2 = mant1(ht2_2, "h"), mant1(ht3_2, "h")
        elif hmode == "entry":
            ht2_0, ht2_2, ht3_0, ht3_1, ht3_2 = (mant1(v, "h") for v in
                                                 (ht2_0, ht2_2, ht3_0, ht3_1, ht3_2))
        elif hmode == "q6.9":
            ht2_0, ht2_2, ht3_0, ht3_1, ht3_2 = (fixq(v, 9, "h69") for v in
                                                 (ht2_0, ht2_2, ht3_0, ht3_1, ht3_2))
        rows = (
            (ht2_0, zero, ht2_2, yt2, d2),
            (ht3_0, ht3_1, ht3_2, yt3, d3),
        )
        x_prior = x.copy()
        # 4a. Angle rows.
        rho = d0 * i1
        c1a, c2a = j3, ht1
        if hmode in ("row", "row1", "row2", "split", "th", "entry", "ang", "fixw", "fixw11") and opt.get("h_ang", True):
            c1a, c2a = mant1(c1a, "h"), mant1(c2a, "h")
        elif hmode == "q6.9":
            c1a, c2a = fixq(c1a, 9, "h69"), fixq(c2a, 9, "h69")
        c2w = c2a * rho
        if hmode in ("row", "row1", "row2", "split", "th", "entry", "ang", "fixw", "fixw11") and opt.get("h_ang", True):
            c2w = mant1(c2w, "h")
        elif hmode == "q6.9":
            c2w = fixq(c2w, 9, "h69")
        g = c1a * c1a + c2w * c2a
        if opt.get("g"):
            g = mant1(g, "g")
        nu = c1a * y3 + c2w * yt1
        sa = d0 + P[:, 2, 2] * g
        good = sa > 0.0
        skipped += ~good
        inv = np.where(good, 1.0 / np.where(good, sa, 1.0), 0.0)
        inv = qi(inv)
        beta = np.where(good, d0 * inv, 1.0)
        nu_s = nu * inv
        if opt.get("angsc"):
            beta, nu_s = mant1(beta, "beta"), mant1(nu_s, "nus")
        p02, p12, p22 = P[:, 0, 2].copy(), P[:, 1, 2].copy(), P[:, 2, 2].copy()
        k0 = (p02 * g) * inv
        k1 = (p12 * g) * inv
        if kmode == "vec":
            k0, k1 = mant_vec("k", k0, k1)
        elif kmode == "entry":
            k0, k1 = mant1(k0, "k"), mant1(k1, "k")
        x[:, 0] += p02 * nu_s
        x[:, 1] += p12 * nu_s
        x[:, 2] += p22 * nu_s
        P[:, 0, 0] -= k0 * p02
        P[:, 0, 1] -= k0 * p12
        P[:, 1, 0] = P[:, 0, 1]
        P[:, 1, 1] -= k1 * p12
        P[:, 0, 2] = P[:, 2, 0] = p02 * beta
        P[:, 1, 2] = P[:, 2, 1] = p12 * beta
        P[:, 2, 2] = p22 * beta
        P = _qP(P, pmode)
        # 4b. Scalar rows.
        for m, (h0, h1, h2, ym, dm) in enumerate(rows, start=2):
            if k < hold:
                break
            dx = x - x_prior
            ym = ym - (h2 * dx[:, 2] + (h0 * dx[:, 0] + h1 * dx[:, 1]))
            p = P[:, :, 0] * h0[:, None] + P[:, :, 1] * h1[:, None] + P[:, :, 2] * h2[:, None]
            sm = h0 * p[:, 0] + h1 * p[:, 1] + h2 * p[:, 2] + dm
            good = sm > 0.0
            skipped += ~good
            inv = np.where(good, 1.0 / np.where(good, sm, 1.0), 0.0)
            inv = qi(inv)
            kg = p * inv[:, None]
            if kmode == "vec":
                kg = mant(kg, "k")
            elif kmode == "entry":
                kg = mant(kg[..., None], "k")[..., 0]
            x = x + kg * ym[:, None]
            P = P - kg[:, :, None] * p[:, None, :]
            P[:, 1, 0], P[:, 2, 0], P[:, 2, 1] = P[:, 0, 1], P[:, 0, 2], P[:, 1, 2]
            P = _qP(P, pmode)
        x[:, 2] = wrap(x[:, 2])
        xs[:, k] = x
        if k >= 200:
            minP22 = min(minP22, float(np.min(np.linalg.eigvalsh(P)[:, 0])) if k % 50 == 0
                         else minP22)
    _count("skipped", int(skipped.sum()))
    STATS["min_eig_P_from_2s"] = minP22
    return xs
