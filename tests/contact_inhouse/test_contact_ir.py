"""A contact-free step compiles none of the contact code (docs/inhouse.md, "Control and contacts
in the step"; tests/rigid/test_control.py does the same for the control).

The contact-free kernels keep their ``contacts`` slot as None; the velocity-level models step in
kernels of their own (velocity3d / velocity2d), which call detection and the row passes. The
LLVM IR of the contact-free symplectic Euler step, compiled afresh, names no function of
sim/collide or of the contact rows, and the IR of the contact step does (so the check can see
them when they are there).
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

IR_SCRIPT = r"""
import json, sys
import numpy as np
from crosscheck.scene.loader import load_case_text
from crosscheck.sim.rigid import compile_model, state_from_scene, splitting3d, velocity3d
from crosscheck.sim.rigid.contact_models import get_contact_model
from crosscheck.sim.rigid import INTEGRATORS
from crosscheck.sim._jit import fresh_llvm_ir
scene = load_case_text(sys.argv[1])
model = compile_model(scene)
s = state_from_scene(model, scene)
INTEGRATORS["symplectic_euler"].advance(model, s, None, None, 1, 1e-3)
free = "\n".join(fresh_llvm_ir(splitting3d.advance_symplectic_euler).values())
out = {"free": {k: k in free for k in ("contact_rows", "collide", "detect3d", "velocity3d")}}
if sys.argv[2] == "both":
    stepper = get_contact_model("sequential_impulse").open(scene, model,
                                                           INTEGRATORS["symplectic_euler"], {})
    stepper.advance(state_from_scene(model, scene), 1, 1e-3)
    step = "\n".join(fresh_llvm_ir(velocity3d.advance3d).values())
    out["contact"] = {k: k in step for k in ("contact_rows", "collide", "detect3d")}
print(json.dumps(out))
"""

CASE = """
[case]
name = "ir"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
[effects]
gravity = [0.0, 0.0, -9.81]
contact = true
[ground]
[[bodies]]
name = "b"
shape = { box = { size = [0.3, 0.2, 0.1] } }
mass = 2.0
position = [0.0, 0.0, 0.05]
"""


def _ir(which: str) -> dict:
    # A process of its own, so each inspected kernel has exactly the one signature this scene
    # gives it; only the inspected kernels are compiled afresh (sim/_jit.fresh_llvm_ir), the
    # kernels they call come from the shared cache.
    res = subprocess.run([sys.executable, "-c", IR_SCRIPT, CASE, which],
                         capture_output=True, text=True, timeout=1800)
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_the_contact_free_step_holds_no_contact_code_and_the_contact_step_does():
    out = _ir("both")
    assert not any(out["free"].values()), out
    assert all(out["contact"].values()), out
