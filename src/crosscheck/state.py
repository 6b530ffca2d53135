"""Trajectory: the normalised state every engine returns, and its .npz file format.

Per body and sample: centre of mass (world), orientation of the declared body frame (unit
quaternion w, x, y, z, sign-continuous; 2D: continuous angle, never wrapped), centre-of-mass
velocity (world) and angular velocity (world; 2D: scalar). ``meta`` holds what is needed to
interpret the arrays with NumPy alone (masses, body-frame inertia about the centre of mass,
engine settings read back, stepping wall time). A run that blew up is truncated at the last
finite sample and carries ``failure = {"time": t, "reason": ...}``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from crosscheck.rotations import sign_continuous

FORMAT_VERSION = 1


@dataclass
class Trajectory:
    t: np.ndarray  # (T,)
    com: np.ndarray  # (T, N, d)
    vel: np.ndarray  # (T, N, d)
    omega: np.ndarray  # (T, N, 3) in 3D, (T, N) in 2D
    quat: np.ndarray | None = None  # (T, N, 4), 3D only
    angle: np.ndarray | None = None  # (T, N), 2D only
    meta: dict[str, Any] = field(default_factory=dict)
    extras: dict[str, np.ndarray] = field(default_factory=dict)  # e.g. out-of-plane drift

    @property
    def dimension(self) -> int:
        return self.com.shape[-1]

    @property
    def n_bodies(self) -> int:
        return self.com.shape[1]

    @property
    def failure(self) -> dict | None:
        return self.meta.get("failure")

    @property
    def wall_time(self) -> float | None:
        return self.meta.get("wall_time")

    # -- file format ------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the DESIGN.md ``.npz`` layout atomically (temporary file, then rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, np.ndarray] = {"t": self.t, "com": self.com, "vel": self.vel,
                                         "omega": self.omega}
        if self.quat is not None:
            arrays["quat"] = self.quat
        if self.angle is not None:
            arrays["angle"] = self.angle
        for name, value in self.extras.items():
            arrays[f"extra_{name}"] = np.asarray(value)
        meta = dict(self.meta, format_version=FORMAT_VERSION)
        arrays["meta"] = np.array(json.dumps(meta, default=_json_default))
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez_compressed(tmp, **arrays)
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        with np.load(Path(path), allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            extras = {k[len("extra_"):]: data[k] for k in data.files if k.startswith("extra_")}
            return cls(
                t=data["t"], com=data["com"], vel=data["vel"], omega=data["omega"],
                quat=data["quat"] if "quat" in data.files else None,
                angle=data["angle"] if "angle" in data.files else None,
                meta=meta, extras=extras,
            )


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


class TrajectoryRecorder:
    """Preallocated sample buffers an adapter fills at the sampling interval.

    ``record`` refuses nothing: a non-finite sample marks the blow-up (time and reason) and tells
    the adapter to stop by returning False, so a blow-up is a result, not an exception.
    """

    def __init__(self, n_samples: int, n_bodies: int, dimension: int):
        self.dimension = dimension
        self.t = np.full(n_samples, np.nan)
        self.com = np.full((n_samples, n_bodies, dimension), np.nan)
        self.vel = np.full((n_samples, n_bodies, dimension), np.nan)
        if dimension == 3:
            self.omega = np.full((n_samples, n_bodies, 3), np.nan)
            self.rot = np.full((n_samples, n_bodies, 4), np.nan)
        else:
            self.omega = np.full((n_samples, n_bodies), np.nan)
            self.rot = np.full((n_samples, n_bodies), np.nan)
        self.count = 0
        self.failure: dict | None = None

    def record(self, t: float, com, rot, vel, omega) -> bool:
        i = self.count
        values = (np.asarray(com), np.asarray(rot), np.asarray(vel), np.asarray(omega))
        if not all(np.all(np.isfinite(v)) for v in values):
            self.failure = {"time": float(t), "reason": "non-finite state"}
            return False
        self.t[i] = t
        self.com[i], self.rot[i], self.vel[i], self.omega[i] = values
        self.count += 1
        return True

    def fail(self, t: float, reason: str) -> None:
        self.failure = {"time": float(t), "reason": reason}

    def finish(self, meta: dict[str, Any], extras: dict[str, np.ndarray] | None = None
               ) -> Trajectory:
        n = self.count
        meta = dict(meta)
        meta["failure"] = self.failure
        traj = Trajectory(t=self.t[:n].copy(), com=self.com[:n].copy(), vel=self.vel[:n].copy(),
                          omega=self.omega[:n].copy(), meta=meta,
                          extras={k: np.asarray(v)[:n] for k, v in (extras or {}).items()})
        if self.dimension == 3:
            traj.quat = sign_continuous(self.rot[:n])
        else:
            # Adapters record the engine's accumulated (continuous) angle. No np.unwrap here: it
            # assumes less than half a turn between samples and would fold a fast spin sampled
            # coarsely (50 rad/s every 0.1 s) back by 2 pi.
            traj.angle = self.rot[:n].copy()
        return traj
