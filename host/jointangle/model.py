"""The accelerometer-array model of Woods & Vikas, §II (notation of docs/design.md §3).

For sensors at r_i on one rigid link (link frame, joint O at r_O):

    a_i = a_O + D(r_i − r_O) y,      D(r) = [[-r1, -r2], [-r2, r1]],  y = [ω², α]ᵀ   (eqs. 1–2)

Stacking the 2-D readings a = [a_1; …; a_N] (2N,):

    F_m = (1/N)[I₂ … I₂]                        mean reading               (eq. 5)
    E   = I₂N − [F_m; …; F_m]                   deviation from the mean    (eq. 6)
    D̃   = [D(r_1 − r̄); …; D(r_N − r̄)]           (eq. 7)
    G   = D̃⁺ E        y = G a                    row 1 = G_ω², row 2 = G_α  (eq. 9)
    F   = F_m + D(r_O − r̄) G      a_O = F a                                 (eq. 8)

Because D(r)ᵀD(r) = |r|² I₂, D̃ᵀD̃ = Σ|r_i − r̄|² I₂, so D̃⁺ = D̃ᵀ / Σ|r_i − r̄|²: the array is
degenerate only when every sensor sits at the same point.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointangle.errors import GeometryError, InputError
from jointangle.io.rig_file import read_rig_text
from jointangle.rig import LinkConfig, Rig, parse_rig

MIN_ARRAY_SPREAD_M = 1e-3  # an array narrower than 1 mm cannot resolve ω² and α


def D(r: np.ndarray) -> np.ndarray:
    """D(r) of eq. 2 for r = [r1, r2]."""
    return np.array([[-r[0], -r[1]], [-r[1], r[0]]], dtype=float)


def rot(theta: np.ndarray | float) -> np.ndarray:
    """R(θ) = [[cos θ, sin θ], [−sin θ, cos θ]], so that vᵃ = R(θ_ab) vᵇ (eq. 12).

    Broadcasts: an array of angles (...,) gives rotation matrices (..., 2, 2).
    """
    c = np.cos(theta)
    s = np.sin(theta)
    return np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)


def drot(theta: np.ndarray | float) -> np.ndarray:
    """R'(θ) = dR/dθ = [[−sin θ, cos θ], [−cos θ, −sin θ]] (used in H, eq. 15)."""
    c = np.cos(theta)
    s = np.sin(theta)
    return np.stack([np.stack([-s, c], -1), np.stack([-c, -s], -1)], -2)


@dataclass(frozen=True)
class ArrayMatrices:
    """The matrices of one link's sensor array."""

    Fm: np.ndarray  # (2, 2N)
    E: np.ndarray  # (2N, 2N)
    Dt: np.ndarray  # (2N, 2)  D̃
    G: np.ndarray  # (2, 2N)
    F: np.ndarray  # (2, 2N)

    @property
    def G_w2(self) -> np.ndarray:
        """Row of G giving ω² (2N,)."""
        return self.G[0]

    @property
    def G_alpha(self) -> np.ndarray:
        """Row of G giving α (2N,)."""
        return self.G[1]

    @property
    def n_sensors(self) -> int:
        return self.G.shape[1] // 2


def array_matrices(positions: np.ndarray, joint: np.ndarray, link: str = "?") -> ArrayMatrices:
    """Build F_m, E, D̃, G and F for sensors at `positions` (N, 2) and the joint at `joint`."""
    r = np.asarray(positions, dtype=float)
    if r.ndim != 2 or r.shape[1] != 2 or r.shape[0] < 2:
        raise GeometryError(f"link {link}: need at least two sensor positions, got {r.shape[0]}",
                            field=f"links.{link}.sensors")
    n = r.shape[0]
    r_bar = r.mean(axis=0)
    spread2 = float(np.sum((r - r_bar) ** 2))
    if spread2 < MIN_ARRAY_SPREAD_M**2:
        raise GeometryError(
            f"link {link}: the sensors are (nearly) coincident (spread {np.sqrt(spread2)*1e3:.3g}"
            f" mm); the array needs sensors at least {MIN_ARRAY_SPREAD_M*1e3:g} mm apart to "
            "separate ω² and α", field=f"links.{link}.sensors")
    Fm = np.tile(np.eye(2), (1, n)) / n  # eq. 5
    E = np.eye(2 * n) - np.tile(Fm, (n, 1))  # eq. 6
    Dt = np.vstack([D(ri - r_bar) for ri in r])  # eq. 7
    Dt_pinv = Dt.T / spread2  # D̃⁺ (see module docstring)
    G = Dt_pinv @ E  # eq. 9
    F = Fm + D(np.asarray(joint, dtype=float) - r_bar) @ G  # eq. 8
    return ArrayMatrices(Fm=Fm, E=E, Dt=Dt, G=G, F=F)


def link_matrices(link: LinkConfig, name: str = "?") -> ArrayMatrices:
    return array_matrices(link.positions(), np.array(link.joint), name)


@dataclass(frozen=True)
class RigModel:
    """Both links' array matrices plus the stacked forms the filters use."""

    a: ArrayMatrices
    b: ArrayMatrices
    dt: float

    @property
    def na(self) -> int:
        """Number of readings (2 N_a) from link a."""
        return self.a.G.shape[1]

    @property
    def nb(self) -> int:
        return self.b.G.shape[1]

    def B(self) -> np.ndarray:
        """B of eq. 11: [[G_αᵃ, 0], [0, G_αᵇ], [0, 0]] (3, 2N_a + 2N_b)."""
        out = np.zeros((3, self.na + self.nb))
        out[0, : self.na] = self.a.G_alpha
        out[1, self.na :] = self.b.G_alpha
        return out


def rig_model(rig: Rig) -> RigModel:
    try:
        return RigModel(a=link_matrices(rig.links["a"], "a"),
                        b=link_matrices(rig.links["b"], "b"), dt=rig.dt)
    except InputError as exc:
        if exc.path is not None or not rig.source:
            raise
        raise type(exc)(exc.reason, path=rig.source, line=exc.line, field=exc.field) from None


def read_checked_rig(path: str | Path) -> tuple[str, Rig]:
    """A rig file's text and its Rig, the geometry checked too (`rig_model`: coincident
    sensors...), for commands that hand the text on to a board or a recording."""
    text = read_rig_text(path)
    rig = parse_rig(text, str(path))
    rig_model(rig)
    return text, rig
