"""Particle level set (Enright, Fedkiw, Ferziger & Mitchell 2002), simplified to what the 2D solver
needs.

Marker particles of both signs are seeded in a band around the surface and advected with the same
velocity and second-order trace as the level set. Semi-Lagrangian advection smears thin features
and sharp corners, losing fluid; a particle that ends up on the wrong side of the surface by more
than its radius has *escaped*, which means the level set moved the surface wrongly there. Each
escaped particle is a small sphere of its sign that the level set must contain: positive ones
raise ``phi+ = max(phi, s (r - |x - xp|))``, negative ones lower ``phi-`` the same way, and the
corrected value at a node is whichever of the two is smaller in magnitude. Correction runs after
advection and again after redistancing; radii are then reset to the distance to the surface
(clamped to [0.1, 0.5] cells), and the band is reseeded periodically.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from crosscheck.sim.fluid.kernels import backtrace, sample

RMIN, RMAX = 0.1, 0.5   # particle radius bounds, cells (Enright et al.)


class Particles:
    def __init__(self, per_cell: int, band: float, reseed_every: int, seed: int):
        self.per_cell = per_cell
        self.band = band
        self.reseed_every = reseed_every
        self.rng = np.random.default_rng(seed)
        self.x = np.empty(0)
        self.y = np.empty(0)
        self.s = np.empty(0)
        self.r = np.empty(0)

    @property
    def count(self) -> int:
        return int(self.x.shape[0])

    def seed(self, phi: np.ndarray, dx: float, solid: np.ndarray) -> None:
        """(Re)seed: keep particles still within the band, top up band cells to ``per_cell``."""
        nx, ny = phi.shape
        keep = _in_band(phi, self.x, self.y, dx, self.band)
        self.x, self.y, self.s, self.r = self.x[keep], self.y[keep], self.s[keep], self.r[keep]
        counts = np.zeros((nx, ny), np.int64)
        if self.count:
            ci = np.clip((self.x / dx).astype(np.int64), 0, nx - 1)
            cj = np.clip((self.y / dx).astype(np.int64), 0, ny - 1)
            np.add.at(counts, (ci, cj), 1)
        need = np.where((np.abs(phi) < self.band * dx) & ~solid,
                        np.maximum(self.per_cell - counts, 0), 0)
        ii, jj = np.nonzero(need)
        reps = need[ii, jj]
        ii = np.repeat(ii, reps)
        jj = np.repeat(jj, reps)
        px = (ii + self.rng.random(ii.shape[0])) * dx
        py = (jj + self.rng.random(jj.shape[0])) * dx
        ph = _phi_at(phi, px, py, dx)
        ok = (np.abs(ph) < self.band * dx) & (np.abs(ph) > RMIN * dx)
        px, py, ph = px[ok], py[ok], ph[ok]
        s = np.where(ph > 0, 1.0, -1.0)
        r = np.clip(np.abs(ph), RMIN * dx, RMAX * dx)
        self.x = np.concatenate([self.x, px])
        self.y = np.concatenate([self.y, py])
        self.s = np.concatenate([self.s, s])
        self.r = np.concatenate([self.r, r])

    def advect(self, up, vp, dt, dx, lx, ly, solid, has_solid) -> None:
        _advect(self.x, self.y, up, vp, dt, dx, lx, ly, solid, has_solid)

    def correct(self, phi: np.ndarray, dx: float) -> int:
        """Correct ``phi`` in place from escaped particles; returns how many escaped."""
        if not self.count:
            return 0
        plus = phi.copy()
        minus = phi.copy()
        n = _correct(phi, plus, minus, self.x, self.y, self.s, self.r, dx)
        if n:
            phi[:] = np.where(np.abs(plus) <= np.abs(minus), plus, minus)
        return n

    def adjust_radii(self, phi: np.ndarray, dx: float) -> None:
        if not self.count:
            return
        ph = _phi_at(phi, self.x, self.y, dx)
        sp = self.s * ph
        # particles escaped by more than the largest radius cannot be explained by the surface
        # any more (they were not corrected back); Enright et al. delete them
        keep = sp > -RMAX * dx
        self.x, self.y, self.s, sp = self.x[keep], self.y[keep], self.s[keep], sp[keep]
        self.r = np.clip(sp, RMIN * dx, RMAX * dx)


def _phi_at(phi, x, y, dx):
    out = np.empty(x.shape[0])
    _sample_many(phi, x, y, dx, out)
    return out


def _in_band(phi, x, y, dx, band):
    if x.shape[0] == 0:
        return np.zeros(0, bool)
    return np.abs(_phi_at(phi, x, y, dx)) < band * dx


@njit(cache=True, parallel=True)
def _sample_many(phi, x, y, dx, out):
    inv = 1.0 / dx
    for k in prange(x.shape[0]):
        out[k] = sample(phi, -0.5, -0.5, x[k], y[k], inv)[0]


@njit(cache=True, parallel=True)
def _advect(x, y, up, vp, dt, dx, lx, ly, solid, has_solid):
    inv = 1.0 / dx
    for k in prange(x.shape[0]):
        # forward trace = backtrace with -dt
        xb, yb = backtrace(x[k], y[k], up, vp, -dt, inv, lx, ly, solid, has_solid)
        x[k] = xb
        y[k] = yb


@njit(cache=True)
def _correct(phi, plus, minus, x, y, s, r, dx):
    nx, ny = phi.shape
    inv = 1.0 / dx
    n = 0
    for k in range(x.shape[0]):
        ph = sample(phi, -0.5, -0.5, x[k], y[k], inv)[0]
        if s[k] * ph >= -r[k]:
            continue
        n += 1
        i0 = int(x[k] * inv - 0.5)
        j0 = int(y[k] * inv - 0.5)
        for a in range(i0, i0 + 2):
            for b in range(j0, j0 + 2):
                if a < 0 or a >= nx or b < 0 or b >= ny:
                    continue
                cx = (a + 0.5) * dx
                cy = (b + 0.5) * dx
                pp = s[k] * (r[k] - np.sqrt((cx - x[k]) ** 2 + (cy - y[k]) ** 2))
                if s[k] > 0:
                    if pp > plus[a, b]:
                        plus[a, b] = pp
                else:
                    if pp < minus[a, b]:
                        minus[a, b] = pp
    return n
