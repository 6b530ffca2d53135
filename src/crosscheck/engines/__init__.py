"""Engine adapters behind one protocol (see base.py). Imported lazily: a missing or broken engine
package makes that engine "not applicable", never breaks the others."""

from __future__ import annotations

import importlib

from crosscheck.engines.base import Engine

# name -> module path and class name; adding an engine is one file plus one line here.
REGISTRY: dict[str, tuple[str, str]] = {
    "inhouse": ("crosscheck.engines.inhouse", "InhouseEngine"),
    "mujoco": ("crosscheck.engines.mujoco", "MujocoEngine"),
    "pybullet": ("crosscheck.engines.pybullet", "PybulletEngine"),
    "pymunk": ("crosscheck.engines.pymunk", "PymunkEngine"),
}


def get_engine(name: str) -> Engine:
    if name not in REGISTRY:
        raise KeyError(f"unknown engine {name!r}; known engines: {sorted(REGISTRY)}")
    module, cls = REGISTRY[name]
    return getattr(importlib.import_module(module), cls)()


def engine_names() -> tuple[str, ...]:
    return tuple(REGISTRY)
