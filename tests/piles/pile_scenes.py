"""The pile scenes of issue 12 point 4 (speed), as case TOML: one source for the benchmark
(benchmarks/bench_piles.py) and the test that checks the scenes are sound (test_pile_scenes.py).

Every scene is written as a case and loaded by crosscheck's own loader, so the engines see what a
committed case would give them (materials, the pair rule, statics), not a hand-built Scene.

* ``spheres_bin(n)``: n spheres (r = 0.05 m, 0.5 kg, friction 0.5, restitution 0) on a staggered
  grid 0.11 m apart (every other layer shifted by a quarter spacing, as cases/contact/
  sphere_pile.toml), dropped into a square bin of four static boxes on the ground plane
  (CONTACTS.md 3b). The bin's side grows with sqrt(n) so the pile is always about ten layers deep:
  the bodies per contact stay the same from 200 to 5000 and the cost per body can be compared.
* ``spheres_ground(n)``: the same grid over the bare ground (no walls): the pile spreads.
* ``boxes_bin(n)``: n 0.1 m cubes, 0.5 kg, the same material, on the same grid with every cube
  turned about a tilted axis by a fixed angle per index (so faces, edges and corners land), into a
  bin.
* ``pile_2d(n)``: n bodies, alternately circles (r = 0.05 m) and squares (0.1 m), 0.5 kg, into a
  2D bin of two static walls, the grid about ten rows deep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from crosscheck.scene.loader import load_case_text
from crosscheck.scene.model import Scene

R = 0.05  # sphere / circle radius (m)
SIDE = 0.1  # cube / square side (m)
MASS = 0.5
SPACING = 0.11  # grid spacing: 1 cm between neighbours at t = 0
LAYERS = 10
FLOOR = 0.06  # height of the lowest centres: 1 cm above the ground for a sphere
WALL = 0.05  # wall thickness (m)
DT = 1e-3


@dataclass(frozen=True)
class Pile:
    """A scene and what a sound end state means for it."""

    name: str
    scene: Scene
    n: int
    dimension: int
    inner: tuple[float, ...]  # (x_lo, x_hi[, y_lo, y_hi]) of the bin's inside; () no bin
    toml: str


def _f(x: float) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return "[" + ", ".join(_f(x) for x in v) + "]"


def _header(name: str, dimension: int, duration: float, engines: list[str]) -> str:
    gravity = "[0.0, 0.0, -9.81]" if dimension == 3 else "[0.0, -9.81]"
    return f"""[case]
name = "{name}"
description = "Benchmark pile (tests/piles/pile_scenes.py)."
tags = ["contact", "pile", "benchmark"]
dimension = {dimension}

[run]
duration = {_f(duration)}
dt = {_f(DT)}
sample_every = {_f(duration / 10)}
engines = {engines!r}

[effects]
gravity = {gravity}
contact = true

[materials.glass]
friction = 0.5
restitution = 0.0

[ground]
material = "glass"

[reference]
kind = "none"
""".replace("'", '"')


def _static(name: str, size, pos) -> str:
    return f"""
[[statics]]
name = "{name}"
shape = {{ box = {{ size = {_vec(size)} }} }}
position = {_vec(pos)}
material = "glass"
"""


def _body(name: str, shape: str, pos, quat=None) -> str:
    orient = f"\norientation = {_vec(quat)}" if quat is not None else ""
    return f"""
[[bodies]]
name = "{name}"
shape = {shape}
mass = {_f(MASS)}
position = {_vec(pos)}{orient}
material = "glass"
"""


def grid3d(n: int) -> tuple[np.ndarray, int]:
    """n centres on the staggered grid, LAYERS deep, and the side (cells per row)."""
    per_layer = math.ceil(n / LAYERS)
    side = math.ceil(math.sqrt(per_layer))
    out = np.empty((n, 3))
    for i in range(n):
        layer, k = divmod(i, per_layer)
        ix, iy = divmod(k, side)
        shift = 0.25 * SPACING * (layer % 2)
        out[i] = [(ix - (side - 1) / 2) * SPACING + shift,
                  (iy - (side - 1) / 2) * SPACING + shift, FLOOR + layer * SPACING]
    return out, side


def _bin3d(centres: np.ndarray, reach: float) -> tuple[str, tuple[float, ...]]:
    """Four walls 2 cm clear of the grid (``reach``: a body's farthest point from its centre),
    as high as the highest start plus 0.1 m: nothing is dropped over them."""
    half = float(np.abs(centres[:, :2]).max()) + reach + 0.02
    top = float(centres[:, 2].max())
    h = top + 0.1  # walls above the highest start: nothing can be dropped over them
    size_x, size_y = [WALL, 2 * half + 2 * WALL, h], [2 * half, WALL, h]
    off = half + WALL / 2
    text = (_static("wall_east", size_x, [off, 0, h / 2])
            + _static("wall_west", size_x, [-off, 0, h / 2])
            + _static("wall_north", size_y, [0, off, h / 2])
            + _static("wall_south", size_y, [0, -off, h / 2]))
    return text, (-half, half, -half, half)


def spheres(n: int, *, walls: bool = True, duration: float = 1.0,
            engines=("inhouse", "mujoco", "pybullet")) -> Pile:
    centres, _ = grid3d(n)
    name = f"spheres_{'bin' if walls else 'ground'}_{n}"
    text = _header(name, 3, duration, list(engines))
    inner: tuple[float, ...] = ()
    if walls:
        walls_text, inner = _bin3d(centres, R)
        text += walls_text
    shape = f"{{ sphere = {{ radius = {_f(R)} }} }}"
    text += "".join(_body(f"s{i}", shape, c) for i, c in enumerate(centres))
    return Pile(name, load_case_text(text, name), n, 3, inner, text)


def _tilt(i: int) -> list[float]:
    """A fixed rotation per index (w, x, y, z): 0-40 degrees about an axis that turns with i."""
    angle = math.radians(10.0 * (i % 5))
    a = 2.399963 * i  # golden angle: axes spread over the horizontal directions
    axis = np.array([math.cos(a), math.sin(a), 0.5])
    axis /= np.linalg.norm(axis)
    s = math.sin(angle / 2)
    return [math.cos(angle / 2), *(s * axis)]


def boxes(n: int, *, walls: bool = True, duration: float = 1.0,
          engines=("inhouse", "mujoco", "pybullet")) -> Pile:
    """Cubes on the grid: a tilted cube's half-diagonal (0.0866 m) can exceed the 0.055 m half
    spacing, so the grid is spread to 0.18 m (no overlap at t = 0 for any orientation); into a
    bin, or (``walls=False``) onto the bare ground."""
    centres, _ = grid3d(n)
    centres = centres * BOX_SPREAD
    centres[:, 2] += FLOOR * (1 - BOX_SPREAD) + 0.04  # lowest cube's corner 1 cm above ground
    name = f"boxes_{'bin' if walls else 'ground'}_{n}"
    text = _header(name, 3, duration, list(engines))
    inner: tuple[float, ...] = ()
    if walls:
        walls_text, inner = _bin3d(centres, HALF_DIAGONAL)
        text += walls_text
    shape = f"{{ box = {{ size = {_vec([SIDE] * 3)} }} }}"
    text += "".join(_body(f"b{i}", shape, c, _tilt(i)) for i, c in enumerate(centres))
    return Pile(name, load_case_text(text, name), n, 3, inner, text)


BOX_SPREAD = 0.18 / SPACING
HALF_DIAGONAL = SIDE * math.sqrt(3) / 2


def pile_2d(n: int, *, duration: float = 1.0, engines=("inhouse", "pymunk")) -> Pile:
    """Alternating circles and squares on a staggered 2D grid, ROWS deep, into a 2D bin."""
    rows = 2 * LAYERS
    per_row = math.ceil(n / rows)
    spacing = 0.15  # a square's half-diagonal is 0.071 m: 0.15 m apart never overlap
    centres = np.empty((n, 2))
    for i in range(n):
        row, k = divmod(i, per_row)
        shift = 0.25 * spacing * (row % 2)
        centres[i] = [(k - (per_row - 1) / 2) * spacing + shift, FLOOR + 0.02 + row * spacing]
    half = 0.5 * (per_row - 1) * spacing + 0.25 * spacing + 0.071 + 0.02
    h = float(centres[:, 1].max()) + 0.1
    name = f"pile_2d_{n}"
    text = _header(name, 2, duration, list(engines))
    text += _static("wall_east", [WALL, h], [half + WALL / 2, h / 2])
    text += _static("wall_west", [WALL, h], [-half - WALL / 2, h / 2])
    circle = f"{{ circle = {{ radius = {_f(R)} }} }}"
    square = f"{{ box = {{ size = {_vec([SIDE, SIDE])} }} }}"
    for i, c in enumerate(centres):
        text += _body(f"q{i}", square, c) if i % 2 else _body(f"c{i}", circle, c)
    return Pile(name, load_case_text(text, name), n, 2, (-half, half), text)


def with_mujoco_solver(pile: Pile, solver: str) -> Pile:
    """The same scene with ``[engine_options.mujoco] solver`` set (the other engines ignore it)."""
    text = pile.toml + f'\n[engine_options.mujoco]\nsolver = "{solver}"\n'
    return Pile(pile.name, load_case_text(text, pile.name), pile.n, pile.dimension, pile.inner,
                text)
