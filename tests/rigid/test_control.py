"""The in-house step's control and contacts arguments (docs/inhouse.md, "Control and contacts").

* A Control holding a constant wrench equal to a scene's constant load gives the load's
  trajectory, for every integrator, 2D and 3D: to round-off in 3D, where the control is summed
  per body before the springs scatter and the loads after them; bit for bit in 2D and in 3D
  without springs (the same additions in the same order).
* ``step`` (state_in -> state_out) n times equals ``advance`` by n; state_in is left alone.
* A control-free step holds no control code: the LLVM IR of the force pass compiled fresh with
  ``control=None`` never mentions the Control type, and with a Control it does.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from crosscheck.scene.loader import load_case_text
from crosscheck.sim.rigid import INTEGRATORS, Control, advance, compile_model, state_from_scene
from crosscheck.sim.rigid import step as rigid_step


def _scene(dim: int, springs: bool = True):
    if dim == 3:
        body = """shape = { box = { size = [0.3, 0.2, 0.1] } }
com = [0.03, -0.02, 0.01]
velocity = [1.0, -0.5, 0.25]
angular_velocity = [3.0, -7.0, 5.0]
orientation = { axis = [1.0, 2.0, 3.0], angle = 0.7 }"""
        vec, load = "[0.4, 0.3, 1.0]", 'force = [0.5, 0.0, -0.2]\ntorque = [0.01, 0.02, -0.03]'
        attach, grav = "[0.15, 0.05, -0.02]", "[0.0, 0.0, -9.81]"
    else:
        body = """shape = { box = { size = [0.3, 0.2] } }
velocity = [1.0, -0.5]
angular_velocity = 3.0
orientation = 0.4"""
        vec, load = "[0.4, 0.3]", "force = [0.5, -0.2]\ntorque = 0.03"
        attach, grav = "[0.15, 0.05]", "[0.0, -9.81]"
    spring = f"""[[effects.springs]]
a = "b"
attach_a = {attach}
anchor = {vec}
stiffness = 30.0
damping = 0.7
rest_length = 0.2
""" if springs else ""
    return load_case_text(f"""
[case]
name = "control"
dimension = {dim}
[run]
duration = 0.1
dt = 1e-3
[effects]
gravity = {grav}
{spring}[[effects.drag]]
linear = 0.3
angular = 0.004
[[effects.loads]]
body = "b"
{load}
[[bodies]]
name = "b"
mass = 2.0
position = [0.1, -0.2{", 0.5" if dim == 3 else ""}]
{body}
""")


def _control_of_loads(model) -> Control:
    control = Control.zeros(model)
    for k, i in enumerate(model.loads.body):
        control.force[i] += model.loads.force[k]
        control.torque[i] += model.loads.torque[k]
    return control


@pytest.mark.parametrize("dim", [3, 2])
@pytest.mark.parametrize("springs", [True, False])
@pytest.mark.parametrize("name", list(INTEGRATORS))
def test_control_equal_to_the_load_gives_the_load_trajectory(name, dim, springs):
    scene = _scene(dim, springs)
    model = compile_model(scene)
    free = model.without("loads")
    control = _control_of_loads(model)
    a, b = state_from_scene(model, scene), state_from_scene(model, scene)
    for _ in range(5):  # several calls: the control is re-read on every one
        advance(model, a, None, None, 20, 1e-3, name)
        advance(free, b, control, None, 20, 1e-3, name)
    for x, y in zip(a.arrays(), b.arrays(), strict=True):
        if dim == 2 or not springs:
            np.testing.assert_array_equal(x, y)
        else:
            np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-14)
    # ... and the control's wrench did something: with a zero control (the same compiled step:
    # control=None would compile another specialisation of every integrator for nothing) the
    # motion differs.
    c = state_from_scene(model, scene)
    advance(free, c, Control.zeros(free), None, 100, 1e-3, name)
    assert not np.allclose(c.P, b.P, rtol=0, atol=1e-6)


@pytest.mark.parametrize("dim", [3, 2])
def test_step_n_times_is_advance_by_n(dim):
    scene = _scene(dim)
    model = compile_model(scene)
    for name in INTEGRATORS:
        s_in = state_from_scene(model, scene)
        ref = s_in.copy()
        fused = s_in.copy()
        advance(model, fused, None, None, 7, 1e-3, name)
        out = s_in.copy()
        rigid_step(model, s_in, out, None, None, 1e-3, name)
        for x, y in zip(s_in.arrays(), ref.arrays(), strict=True):
            np.testing.assert_array_equal(x, y)  # state_in untouched
        for _ in range(6):
            rigid_step(model, out, out, None, None, 1e-3, name)
        for x, y in zip(out.arrays(), fused.arrays(), strict=True):
            np.testing.assert_array_equal(x, y)


def test_contacts_are_refused_by_integrators_that_pair_with_no_contact_model():
    scene = _scene(3)
    model = compile_model(scene)
    refusing = [name for name, integ in INTEGRATORS.items() if not integ.contact]
    assert refusing == ["implicit_euler"]
    for name in refusing:
        with pytest.raises(ValueError, match="cannot run with contact"):
            advance(model, state_from_scene(model, scene), None, object(), 1, 1e-3, name)


IR_SCRIPT = r"""
import json, sys
import numpy as np
from crosscheck.scene.loader import load_case_text
from crosscheck.sim.rigid import Control, compile_model, state_from_scene
from crosscheck.sim.rigid import forces3d
import numba
from crosscheck.sim._jit import fresh_llvm_ir
scene = load_case_text(sys.argv[1])
model = compile_model(scene).without("springs", "drag", "loads")
n = model.n_bodies
out = {}
for label, control in (("none", None), ("control", Control.zeros(model))):
    s = state_from_scene(model, scene)
    R, v, w, F, T = np.empty((n, 3, 3)), *(np.empty((n, 3)) for _ in range(4))
    forces3d.evaluate(*model.kernel_args(), control, None, *s.arrays(), R, v, w, F, T)
    irs = [ir for sig, ir in fresh_llvm_ir(forces3d.evaluate).items()
           if str(sig[5]) == str(numba.typeof(control))]
    out[label] = {"lines": irs[0].count("\n"), "Control": "Control" in irs[0]}
print(json.dumps(out))
"""


def test_control_free_force_pass_holds_no_control_code():
    # The force pass compiled afresh (sim/_jit.fresh_llvm_ir: a cached function has no IR to
    # inspect), which every integrator calls once per stage and where the control is read.
    res = subprocess.run([sys.executable, "-c", IR_SCRIPT, _CASE_3D], capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["none"]["Control"] is False
    assert out["control"]["Control"] is True  # the check can see it when it is there
    assert out["none"]["lines"] < out["control"]["lines"]


_CASE_3D = """
[case]
name = "ir"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
[effects]
gravity = [0.0, 0.0, -9.81]
[[bodies]]
name = "b"
shape = { box = { size = [0.3, 0.2, 0.1] } }
mass = 2.0
position = [0.0, 0.0, 0.0]
"""
