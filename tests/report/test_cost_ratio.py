"""Cost is reported as a ratio against MuJoCo measured in the same run (the project's speed
standard); the pairing rule decides which MuJoCo cell a ratio divides by."""

from crosscheck.report.results import mujoco_cost_ratios


def _cell(case, engine, integrator, dt, cost):
    return {"id": f"{case}:{engine}-{integrator}@{dt}", "case": case, "engine": engine,
            "integrator": integrator, "dt": dt, "cost": cost}


def test_pairs_same_integrator_then_mujoco_default_and_never_across_steps_or_cases():
    cells = [
        _cell("a", "mujoco", "rk4", 1e-3, 0.04), _cell("a", "mujoco", "euler", 1e-3, 0.01),
        _cell("a", "inhouse", "rk4", 1e-3, 0.004),           # vs MuJoCo rk4: 0.1
        _cell("a", "pybullet", "multibody", 1e-3, 0.02),    # vs MuJoCo euler (default): 2
        _cell("a", "inhouse", "rk4", 5e-4, 0.008),           # MuJoCo did not run this step
        _cell("fluid", "inhouse", "semi_lagrangian", 1e-3, 1.0),  # MuJoCo does not run fluids
    ]
    r = mujoco_cost_ratios(cells)
    assert r["a:inhouse-rk4@0.001"] == 0.004 / 0.04
    assert r["a:pybullet-multibody@0.001"] == 0.02 / 0.01
    assert r["a:mujoco-rk4@0.001"] == 1.0
    assert "a:inhouse-rk4@0.0005" not in r and "fluid:inhouse-semi_lagrangian@0.001" not in r


def test_fluid_plots_one_embedded_with_its_type_the_heavy_ones_linked(tmp_path):
    # The fluid adapter writes a validation plot, a frame sheet and a GIF animation: the page
    # embeds the validation plot (a data URI carrying the type of what it holds) and links the
    # frames and the animation, files in the report folder, by relative paths.
    import base64
    import re

    from crosscheck.report.html import render
    from crosscheck.report.results import new_document

    folder = tmp_path / "plots" / "c" / "inhouse-x-dt0.01"
    folder.mkdir(parents=True)
    validation, frames, gif = (folder / "c-x-validation.png", folder / "c-x-frames.png",
                               folder / "c-x-surface.gif")
    for path in (validation, frames):
        path.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 16)
    gif.write_bytes(b"GIF89a" + b"\0" * 16)
    doc = new_document()
    doc["cells"] = [{"id": "c", "case": "c", "engine": "inhouse", "integrator": "x", "dt": 0.01,
                     "status": "pass", "metrics": {},
                     "plots": [str(frames), str(validation), str(gif)]}]
    html = render(doc, doc["cells"], tmp_path)
    found = re.findall(r'src="data:(image/[a-z+]+);base64,([A-Za-z0-9+/=]+)"', html)
    assert [(mime, base64.b64decode(data)[:4]) for mime, data in found] == \
        [("image/png", b"\x89PNG")]
    assert "href='plots/c/inhouse-x-dt0.01/c-x-frames.png'>frames</a>" in html
    assert "href='plots/c/inhouse-x-dt0.01/c-x-surface.gif'>animation</a>" in html
