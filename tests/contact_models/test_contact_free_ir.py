"""A contact-free force pass holds no contact code: the LLVM IR of ``forces3d.evaluate`` compiled
afresh with ``contacts=None`` never mentions the contact kernels, and with the penalty model's
argument it does (the check can see them)."""

from __future__ import annotations

import json
import subprocess
import sys

IR_SCRIPT = r"""
import json, sys
import numpy as np
from crosscheck.scene.loader import load_case_text
from crosscheck.sim.rigid import compile_model, get_integrator, state_from_scene
from crosscheck.sim.rigid import forces3d
from crosscheck.sim.rigid.contact_models import get_contact_model
import numba
from crosscheck.sim._jit import fresh_llvm_ir
scene = load_case_text(sys.argv[1])
model = compile_model(scene)
n = model.n_bodies
stepper = get_contact_model("penalty").open(scene, model, get_integrator("rk4"), {})
stepper._set_step(1e-3)
out = {}
for label, contacts in (("none", None), ("penalty", stepper.arg)):
    s = state_from_scene(model, scene)
    R, v, w, F, T = np.empty((n, 3, 3)), *(np.empty((n, 3)) for _ in range(4))
    forces3d.evaluate(*model.kernel_args(), None, contacts, *s.arrays(), R, v, w, F, T)
    irs = [ir for sig, ir in fresh_llvm_ir(forces3d.evaluate).items()
           if str(sig[6]) == str(numba.typeof(contacts))]
    out[label] = {"lines": irs[0].count("\n"),
                  "contact": any(k in irs[0] for k in ("penalty_rows3d", "detect3d"))}
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


def test_contact_free_force_pass_holds_no_contact_code():
    # Only forces3d.evaluate is compiled afresh (sim/_jit.fresh_llvm_ir); what it calls comes
    # from the shared cache.
    res = subprocess.run([sys.executable, "-c", IR_SCRIPT, CASE], capture_output=True,
                         text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["none"]["contact"] is False
    assert out["penalty"]["contact"] is True
    assert out["none"]["lines"] < out["penalty"]["lines"]
