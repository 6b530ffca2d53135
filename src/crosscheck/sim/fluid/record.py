"""FluidRecord: what one fluid run returns, saved like a trajectory (``.npz``, NumPy alone).

Layout of the ``.npz`` (all keys plain arrays, no pickling):

* ``t`` (T,): sample times of the scalar series, s;
* ``series.<name>`` (T,): scalar series: ``volume`` (m^2 per unit depth), ``kinetic_energy``
  (J/m), ``max_speed`` (m/s), ``front`` (m), ``surface_height`` (m), ``dt`` (s), ...; with a
  coupled body ``body_x.<name>``, ``body_y.<name>``, ``body_angle.<name>``, ``body_vx.<name>``,
  ``body_vy.<name>``, ``body_omega.<name>`` (centre of mass, world frame), the fluid's force and
  moment on it ``body_force_x.<name>``, ``body_force_y.<name>``, ``body_torque.<name>``, and
  ``body_energy``, ``potential_energy`` (the fluid's), ``total_energy`` (J/m);
* ``field_t`` (F,): times of the field snapshots, s;
* ``field.<name>`` (F, ...), float32: ``u`` (F, nx+1, ny) x-face velocity (m/s), ``v``
  (F, nx, ny+1), ``phi`` (F, nx, ny) level set at cell centres (m), ``p`` (F, nx, ny) pressure (Pa);
* ``meta`` () str: JSON: case, integrator, grid, dt statistics, CFL, wall time total and per phase;
* ``failure`` () str: JSON ``null`` or ``{"time": s, "reason": text}``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


@dataclass
class FluidRecord:
    t: np.ndarray
    series: dict[str, np.ndarray]
    field_t: np.ndarray
    fields: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)
    failure: dict[str, Any] | None = None

    @property
    def ok(self) -> bool:
        return self.failure is None

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, np.ndarray] = {"t": np.asarray(self.t),
                                         "field_t": np.asarray(self.field_t)}
        for k, v in self.series.items():
            arrays[f"series.{k}"] = np.asarray(v)
        for k, v in self.fields.items():
            arrays[f"field.{k}"] = np.asarray(v)
        arrays["meta"] = np.array(json.dumps(self.meta, default=_json_default))
        arrays["failure"] = np.array(json.dumps(self.failure, default=_json_default))
        with open(path, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> FluidRecord:
        with np.load(path, allow_pickle=False) as z:
            series = {k[len("series."):]: z[k] for k in z.files if k.startswith("series.")}
            fields = {k[len("field."):]: z[k] for k in z.files if k.startswith("field.")}
            return cls(t=z["t"], series=series, field_t=z["field_t"], fields=fields,
                       meta=json.loads(str(z["meta"])), failure=json.loads(str(z["failure"])))


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")
