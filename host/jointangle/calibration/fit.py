"""Calibration maths for one accelerometer: â = S v + o (Woods & Vikas, Appendix IV).

v is the raw reading (sensor frame, m/s²), â the calibrated specific force in the sensor's
*nominal* frame (the frame at `rotation_deg` about z from the link, docs/design.md §4), so S absorbs
scale, cross-axis coupling and the misalignment of the real axes; estimators/base.py
`sensor_to_link` applies â = S v + o and then the nominal mounting rotation.

Three fits:
- `fit_linear` — Appendix IV: known specific forces â_j in P ≥ 4 static poses, y = 𝒱⁺𝒜.
- `fit_gravity_magnitude` — Madgwick §6.2.1 (eqs. 38–40): |T v_j + c| = g over arbitrary
  static orientations, no fixture; T symmetric (see there), c the offset.
- `fit_alignment` — Madgwick §6.2.2 (eqs. 41–42): the rotation R taking the intrinsically
  calibrated readings onto reference directions (known link poses, or a fiducial sensor),
  solved in closed form (SVD) rather than by BFGS: the same minimiser.
The total calibration of the fixture-free route is then S = R T, o = R c.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares


@dataclass(frozen=True)
class LinearFit:
    S: np.ndarray  # (3, 3)
    offset: np.ndarray  # (3,) m/s²
    residuals: np.ndarray  # (P, 3) m/s², â_j − (S v_j + o)
    condition: float  # of the column-scaled pose matrix [v/g 1]


def fit_linear(v: np.ndarray, a: np.ndarray, g: float) -> LinearFit:
    """Appendix IV: least-squares S, o from raw pose means v (P, 3) and known â (P, 3).

    The paper stacks â_j = V(v_j) y with V(v) = [[vᵀ 0 0 1 0 0], [0 vᵀ 0 0 1 0],
    [0 0 vᵀ 0 0 1]] and y = [S₁₁ … S₃₃, o₁ o₂ o₃]ᵀ, so y = 𝒱⁺𝒜 (𝒱 3P×12). 𝒱 is block
    structured: row m of S and o_m meet only the m-th component of every â_j, so the 12-unknown
    problem splits into three 4-unknown ones sharing X = [v_j 1] (P×4):
        X [S_mᵀ; o_m] = [â_{1m} … â_{Pm}]ᵀ,  m = 1, 2, 3.
    Solved together as X Y = A with Y = [Sᵀ; oᵀ] (4×3) — the same y as 𝒱⁺𝒜.
    Needs four poses whose [v 1] rows are independent (not all on one plane).
    """
    v = np.asarray(v, dtype=float)
    a = np.asarray(a, dtype=float)
    x = np.hstack([v, np.ones((len(v), 1))])
    y, *_ = np.linalg.lstsq(x, a, rcond=None)
    S = y[:3].T
    o = y[3]
    xs = np.hstack([v / g, np.ones((len(v), 1))])
    sv = np.linalg.svd(xs, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    return LinearFit(S=S, offset=o, residuals=a - (v @ S.T + o), condition=cond)


@dataclass(frozen=True)
class MagnitudeFit:
    T: np.ndarray  # (3, 3) symmetric
    c: np.ndarray  # (3,) m/s², intrinsic offset: u = T v + c
    residuals: np.ndarray  # (P,) m/s², |T v_j + c| − g
    condition: float  # of the column-scaled Jacobian at the solution
    success: bool


_SYM = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def _unpack(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.empty((3, 3))
    for k, (i, j) in enumerate(_SYM):
        t[i, j] = t[j, i] = p[k]
    return t, p[6:9]


def fit_gravity_magnitude(v: np.ndarray, g: float) -> MagnitudeFit:
    """Madgwick §6.2.1: the intrinsic calibration u = T v + c making |u| = g in every pose.

    Madgwick writes α = S K u − b (eq. 38) and solves min Σ_j (g − |S K u_j − b|)² (eq. 40)
    by BFGS, noting sensitivity to the initial gains. Its 12 unknowns hold 3 that no magnitude
    can see — a rotation R leaves |R u| unchanged — which is what makes the problem ill-posed.
    We remove them: any invertible matrix factors as R P with P symmetric positive definite
    (polar decomposition), so the magnitude fits P = T (6 unknowns) and c (3), and the rotation
    is left to the alignment step (§6.2.2). Residuals r_j = |T v_j + c| − g are minimised by
    Levenberg–Marquardt with the analytic Jacobian
        ∂r_j/∂T_ii = u_i v_i / |u|,  ∂r_j/∂T_ik = (u_i v_k + u_k v_i) / |u| (i ≠ k),
        ∂r_j/∂c = uᵀ / |u|,
    starting from T = I, c = 0 (the raw readings are within a few % of calibrated ones).
    Needs at least 9 poses spread over the sphere (12 or more recommended).
    """
    v = np.asarray(v, dtype=float)

    def resid(p: np.ndarray) -> np.ndarray:
        t, c = _unpack(p)
        return np.asarray(np.linalg.norm(v @ t.T + c, axis=1) - g)

    def jac(p: np.ndarray) -> np.ndarray:
        t, c = _unpack(p)
        u = v @ t.T + c
        nu = np.linalg.norm(u, axis=1)[:, None]
        cols = []
        for i, k in _SYM:
            if i == k:
                cols.append(u[:, i] * v[:, i])
            else:
                cols.append(u[:, i] * v[:, k] + u[:, k] * v[:, i])
        return np.hstack([np.stack(cols, axis=1), u]) / nu

    p0 = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    method = "lm" if len(v) >= 9 else "trf"
    sol = least_squares(resid, p0, jac=jac, method=method, x_scale="jac")
    t, c = _unpack(sol.x)
    j = jac(sol.x)
    j = j / np.maximum(np.linalg.norm(j, axis=0), 1e-300)
    sv = np.linalg.svd(j, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if len(v) >= 9 and sv[-1] > 0 else float("inf")
    return MagnitudeFit(T=t, c=c, residuals=resid(sol.x), condition=cond,
                        success=bool(sol.success))


@dataclass(frozen=True)
class AlignmentFit:
    R: np.ndarray  # (3, 3) rotation: reference ≈ R u
    residuals: np.ndarray  # (P,) rad, angle between R u_j and the reference r_j
    condition: float  # ratio of the two largest singular values of the reference set


def fit_alignment(u: np.ndarray, ref: np.ndarray) -> AlignmentFit:
    """Madgwick §6.2.2: the rotation R minimising Σ_j |R u_j − r_j|² (eq. 42, written there
    with the quaternion of R: r = q* ⊗ u ⊗ q, eq. 41).

    This is Wahba's problem; its minimiser in closed form (Kabsch): with B = Σ_j r_j u_jᵀ =
    U Σ Vᵀ, R = U diag(1, 1, det(U Vᵀ)) Vᵀ. Both vectors are normalised first so every pose
    weighs the same. Needs two non-parallel reference directions.
    """
    un = np.asarray(u, dtype=float)
    rn = np.asarray(ref, dtype=float)
    un = un / np.linalg.norm(un, axis=1, keepdims=True)
    rn = rn / np.linalg.norm(rn, axis=1, keepdims=True)
    b = rn.T @ un
    uu, _, vt = np.linalg.svd(b)
    d = np.sign(np.linalg.det(uu @ vt)) or 1.0
    r = uu @ np.diag([1.0, 1.0, d]) @ vt
    ang = np.arccos(np.clip(np.sum((un @ r.T) * rn, axis=1), -1.0, 1.0))
    # Directions span at least a plane when the second singular value of Σ r rᵀ is not ~0.
    sr = np.linalg.svd(rn, compute_uv=False)
    cond = float(sr[0] / sr[1]) if len(sr) > 1 and sr[1] > 0 else float("inf")
    return AlignmentFit(R=r, residuals=ang, condition=cond)


def calibration_error(S: np.ndarray, o: np.ndarray, m: np.ndarray, b: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """What is left of a sensor's error after calibration, given its true model v = M f + b:
    the calibrated reading is S v + o = (I + E) f + e, so E = S M − I and e = S b + o.

    diag(E) are the remaining scale errors, the antisymmetric part of E a remaining small
    rotation (misalignment), its symmetric off-diagonal part remaining cross-axis coupling,
    and e the remaining offset. These are recovered-minus-injected in a form that does not
    depend on how an error is split between misalignment and cross-axis terms."""
    e_mat = S @ m - np.eye(3)
    return e_mat, S @ b + o


def rotation_error_deg(e_mat: np.ndarray) -> np.ndarray:
    """Small rotation vector (degrees) of the antisymmetric part of E: ½[E₃₂−E₂₃, E₁₃−E₃₁,
    E₂₁−E₁₂] — the misalignment left after calibration."""
    w = 0.5 * np.array([e_mat[2, 1] - e_mat[1, 2], e_mat[0, 2] - e_mat[2, 0],
                        e_mat[1, 0] - e_mat[0, 1]])
    return np.asarray(np.degrees(w))
