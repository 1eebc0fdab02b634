"""Fill Numba's cache before the suite's processes start, in two processes with disjoint work.

On a fresh clone every kernel compiles on its first call, in whichever test process calls it first; the two test
processes (``make test``: ``pytest -n 2``) then both compile the largest kernels at the same time (the Gauss-Seidel
cloth kernel, ~40 s; the body collider's, ~13 s), each for itself. ``conftest.pytest_configure`` runs this file
twice at once before the test processes start, so each kernel compiles once, on one core, through the engine's own
paths: ``gs`` drapes the demo skirt for two frames (the collider, the cloth kernel, the contacts, the drape's
metrics) and draws it (the preview's rasteriser); ``rest`` builds a body to measurements (the girth and section
kernels) and steps a tiny pinned sheet on the projective solver (its kernels and the sparse factor). A kernel
they miss still compiles where a test first calls it, as before. Measured on a clean clone, two quiet cores: the
tests took 456 s after 106 s of this, against 590 s without it (single runs).

    python tests/_warm_kernels.py gs|rest
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _skirt_drape(settings):
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import default_body
    from vfit_engine.drape import prepare_drape, run_drape
    from vfit_engine.garment.garment import load_garment

    model = BodyModel.load()
    body = default_body(model, "female")
    setup = prepare_drape(load_garment(ROOT / "data" / "garments" / "skirt.obj"), body, model, settings=settings)
    return model, body, setup, run_drape(setup, settings)


def gs():
    """The garment-mesh drape's kernels (the Gauss-Seidel solver, the collider, contacts, metrics), the preview's."""
    from vfit_engine.drape import DrapeSettings
    from vfit_engine.preview import render_image

    model, body, setup, result = _skirt_drape(DrapeSettings(max_frames=2))
    render_image(body.verts, model.body_tris, result.pos, setup.garment.mesh.triangles(), size=(300, 150))


def rest():
    """The body's measurement kernels, the projective solver's, the preview's."""
    from vfit_engine.body.model import BodyModel
    from vfit_engine.body.resolve import resolve_body
    from vfit_engine.sim.model import Model
    from vfit_engine.sim.solver_pd import SolverPD
    from vfit_engine.sim.springs import grid_polygons

    model = BodyModel.load()
    resolve_body(model, targets={"height": 1.68, "waist": 0.72, "hips": 0.98, "bust": 0.90}, gender="female")
    pos, fv, fo = grid_polygons(12, 12, 0.3, 0.3)
    solver = SolverPD(Model.from_polygons(fv, fo, pos, "cotton", pin_indices=[0, 11]))
    state = solver.init_state(1.0 / 120.0)
    for _ in range(2):
        solver.step_frame(state, 1.0 / 60.0)


if __name__ == "__main__":
    {"gs": gs, "rest": rest}[sys.argv[1]]()
