"""The pair rule: the one place that decides what friction and restitution two surfaces in contact
have, so that every engine is given the same numbers.

Engines combine two materials differently (MuJoCo takes the maximum friction, Bullet and Chipmunk
the product, Box2D v3 the geometric mean), so giving each engine per-body materials would make them
simulate different physics. crosscheck therefore computes one value per pair, here, and each
adapter programs its engine so that the engine's own combination yields exactly that value (e.g.
sqrt of the pair value on both surfaces for a product rule). The rule is Box2D v3's:

* friction, rolling friction, torsional friction: geometric mean ``sqrt(x_a * x_b)`` (zero when
  either surface is frictionless, symmetric, and the material itself when both are the same);
* restitution: maximum ``max(e_a, e_b)`` (a bouncy ball bounces on a dead floor).

A ``[[contact_pairs]]`` entry overrides any of the four for one unordered pair, the rest still
follow the rule; ``collide = false`` disables the pair. The names are body names, static names
and "ground". Nothing here imports engines or the simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from crosscheck.scene.model import Material, PairOverride, Scene

GROUND = "ground"  # the name of the [ground] plane in pairs (reserved: no body or static has it)
VALUES = ("friction", "restitution", "rolling_friction", "torsional_friction")
RULES = {"friction": "geometric mean", "restitution": "maximum",
         "rolling_friction": "geometric mean", "torsional_friction": "geometric mean"}


@dataclass(frozen=True)
class PairMaterial:
    """The contact values of one unordered pair, what every engine is asked to use."""

    friction: float
    restitution: float
    rolling_friction: float  # m
    torsional_friction: float  # m
    collide: bool = True
    source: str = "rule"  # "rule", or "contact_pairs[i]": the entry for this pair
    overridden: tuple[str, ...] = ()  # the values that entry set; the others follow the rule


@dataclass(frozen=True)
class ContactPair:
    """Two things that can touch, ``a`` always a body; ``kind`` says what ``b`` is."""

    a: str
    b: str
    kind: str  # "body-body", "body-static" or "body-ground"
    material: PairMaterial


def geometric_mean(x: float, y: float) -> float:
    if x == y:
        return x  # exact, where sqrt(x * x) could round
    product = x * y
    if math.isfinite(product) and (product > 0 or x == 0 or y == 0):
        return math.sqrt(product)
    return math.sqrt(x) * math.sqrt(y)  # the product overflowed or underflowed


def combine(ma: Material, mb: Material) -> PairMaterial:
    """The pair rule alone, without overrides."""
    return PairMaterial(
        friction=geometric_mean(ma.friction, mb.friction),
        restitution=max(ma.restitution, mb.restitution),
        rolling_friction=geometric_mean(ma.rolling_friction, mb.rolling_friction),
        torsional_friction=geometric_mean(ma.torsional_friction, mb.torsional_friction),
    )


def material_of(scene: Scene, name: str) -> Material:
    """The material of a body, a static or the ground, by name."""
    if name == GROUND:
        if scene.ground is None:
            raise ValueError(f"{scene.name}: no [ground] in this case")
        return scene.ground.material
    for thing in (*scene.bodies, *scene.statics):
        if thing.name == name:
            return thing.material
    raise ValueError(f"{scene.name}: no body or static named {name!r}")


def find_override(scene: Scene, a: str, b: str) -> PairOverride | None:
    for entry in scene.pair_overrides:
        if {entry.a, entry.b} == {a, b}:
            return entry
    return None


def pair_material(scene: Scene, a: str, b: str) -> PairMaterial:
    """The values for contact between ``a`` and ``b`` (unordered): the pair rule on their
    materials, with the values a ``[[contact_pairs]]`` entry gives replacing the rule's."""
    rule = combine(material_of(scene, a), material_of(scene, b))
    entry = find_override(scene, a, b)
    if entry is None:
        return rule
    given = {k: getattr(entry, k) for k in VALUES if getattr(entry, k) is not None}
    values = {k: given.get(k, getattr(rule, k)) for k in VALUES}
    return PairMaterial(**values, collide=entry.collide, source=f"contact_pairs[{entry.index}]",
                        overridden=tuple(given))


def pairs(scene: Scene) -> tuple[ContactPair, ...]:
    """Every pair that can touch in a contact scene, each with the values engines must use, in a
    fixed order: body-body (in body order), body-static, body-ground. Fixed geometry never touches
    fixed geometry, so static-static and static-ground pairs are not listed. Pairs disabled by
    ``collide = false`` are listed with ``material.collide`` False: adapters must filter them
    out, since every engine collides everything by default. A scene without ``contact`` has none.

    N bodies make N (N - 1) / 2 body pairs: this list is for showing and checking a case. An
    adapter programs its engine from :func:`material_classes`, whose size does not grow with N.
    """
    if not scene.effects.contact:
        return ()
    classes = material_classes(scene)
    out = []
    names = scene.body_names
    for i, a in enumerate(names):
        out.extend(ContactPair(a, b, "body-body", classes.value(a, b)) for b in names[i + 1:])
    for a in names:
        out.extend(ContactPair(a, s, "body-static", classes.value(a, s))
                   for s in scene.static_names)
    if scene.ground is not None:
        out.extend(ContactPair(a, GROUND, "body-ground", classes.value(a, GROUND))
                   for a in names)
    return tuple(out)


@dataclass(frozen=True)
class MaterialClasses:
    """The surfaces of a contact scene (bodies, statics, "ground") in classes such that the values
    of a pair depend on the two classes alone: surfaces whose materials have equal values share a
    class, and a surface named in a ``[[contact_pairs]]`` entry is a class of its own. Bodies and
    fixed surfaces (statics, the ground) are never in one class: a body touches every other
    surface, fixed geometry touches bodies only, so the members of a class are interchangeable
    (the same pairs, the same values) and a class is all bodies or all fixed (``fixed_class``).
    A pile of N bodies of one material on the ground is two classes, so an engine is programmed
    with a K x K table (per-surface values, the engine's own combination rule, explicit pairs
    only where that rule gives other values) instead of N^2 pairs.
    """

    surfaces: tuple[str, ...]  # bodies, then statics, then "ground"
    fixed: frozenset[str]  # the statics and "ground": fixed geometry never touches fixed geometry
    of: dict[str, int]  # surface name -> class
    members: tuple[tuple[str, ...], ...]  # the surfaces of each class, in surface order
    values: tuple[tuple[PairMaterial, ...], ...]  # K x K: values[i][j], i and j's surfaces

    @property
    def k(self) -> int:
        return len(self.members)

    def fixed_class(self, i: int) -> bool:
        """Whether class i holds fixed surfaces (statics, the ground); else it holds bodies."""
        return self.members[i][0] in self.fixed

    def value(self, a: str, b: str) -> PairMaterial:
        """The values of the pair (a, b), a != b: the same as :func:`pair_material`."""
        return self.values[self.of[a]][self.of[b]]

    def touches(self, a: str, b: str) -> bool:
        """Whether a and b are a pair that can touch (two different surfaces, not both fixed)."""
        return a != b and not (a in self.fixed and b in self.fixed)

    def pairs_between(self, i: int, j: int):
        """Every pair (a, b) that can touch with a in class i and b in class j (each unordered
        pair once when i == j): none when both classes are fixed."""
        if self.fixed_class(i) and self.fixed_class(j):
            return
        mi, mj = self.members[i], self.members[j]
        for x, a in enumerate(mi):
            yield from ((a, b) for b in (mi[x + 1:] if i == j else mj))

    def count(self, i: int, j: int) -> int:
        """How many pairs ``pairs_between(i, j)`` yields, without listing them."""
        if self.fixed_class(i) and self.fixed_class(j):
            return 0
        n = len(self.members[i])
        return n * (n - 1) // 2 if i == j else n * len(self.members[j])

    def class_pairs(self):
        """Every class pair (i, j), i <= j, holding at least one pair that can touch."""
        for i in range(self.k):
            for j in range(i, self.k):
                if self.count(i, j) > 0:
                    yield i, j


def material_classes(scene: Scene) -> MaterialClasses:
    """The scene's surfaces in material classes, each class pair's values from
    :func:`pair_material` on one representative of each (the same values for every member)."""
    named = {n for entry in scene.pair_overrides for n in (entry.a, entry.b)}
    fixed = frozenset(s.name for s in scene.statics) | ({GROUND} if scene.ground else set())
    things = [(b.name, b.material) for b in scene.bodies]
    things += [(s.name, s.material) for s in scene.statics]
    if scene.ground is not None:
        things.append((GROUND, scene.ground.material))
    keys: dict[tuple, int] = {}
    members: list[list[str]] = []
    of: dict[str, int] = {}
    for name, m in things:
        key = (("named", name) if name in named else
               ("values", name in fixed, m.friction, m.restitution, m.rolling_friction,
                m.torsional_friction))
        if key not in keys:
            keys[key] = len(members)
            members.append([])
        of[name] = keys[key]
        members[keys[key]].append(name)
    reps = [m[0] for m in members]
    values = tuple(tuple(pair_material(scene, a, b) for b in reps) for a in reps)
    return MaterialClasses(tuple(n for n, _ in things), fixed, of,
                           tuple(tuple(m) for m in members), values)
