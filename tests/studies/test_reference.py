"""Data-only scenes: errors against a reference solution are exact through the nested transfer, the
reference is solved once per eps, and the whole scene is the same on 2 ranks as on one."""
from pathlib import Path

import pytest
from mpi4py import MPI

from dolfinx import fem
from signorini_cli import config, studies
from signorini_cli.meshing import meshes
from signorini_cli.problems import measure
from signorini_cli.solve.transfer import transfer
from signorini_cli.studies import reference, stability

ROOT = Path(__file__).resolve().parents[2]
DATA_ONLY = {"problem": {"exact": None, "f": "10"}}
RTOL = 1e-8  # issue 4: a data-only scene agrees to 1e-8 relative on 2 ranks (solver tolerance 1e-10)


def p1(domain, expression):
    u = fem.Function(fem.FunctionSpace(domain.mesh, ("Lagrange", 1)))
    u.interpolate(expression)
    return u


def check_reference_errors_exact(make_config, comm):
    """w, v on the N = 4 level; u_ref = w moved two refinements up. Then u_ref - v is the coarse P1
    function w - v, whose norms the coarse mesh integrates exactly: both ways must agree."""
    cfg = make_config(mesh={"refinements": [4]}, verification={"reference_refinements": 2}, **DATA_ONLY)
    coarse = meshes.build(cfg.mesh, cfg.contact, 4, comm)
    # w > v > 0 on Γ_C (y = 0): the positive parts are the functions, |w - v|^3 a cubic: no kinks
    w = p1(coarse, lambda x: 2 + x[0] + x[1])
    v = p1(coarse, lambda x: 1 + x[0] ** 2)
    ref = reference.Reference(cfg, comm)
    u_ref = transfer(w, fem.FunctionSpace(ref.mesh().mesh, ("Lagrange", 1)))
    found = ref.errors(v, u_ref, 0.5, with_contact=True)
    direct = measure.difference_norms(v, w)
    ds_c = coarse.ds_c(measure.contact_error_degree(v.function_space))
    direct.update(measure.contact_errors(v, w, 0.5, cfg.alpha, ds_c, direct["H1"]))
    assert set(found) == {f"{name}_ref" for name in direct}
    for name, value in direct.items():
        assert found[f"{name}_ref"] == pytest.approx(value, rel=1e-12)  # round-off of two quadratures
    # a successive difference of a function with itself vanishes, with another one it is their distance
    fine = transfer(w, fem.FunctionSpace(meshes.build(cfg.mesh, cfg.contact, 8, comm).mesh, ("Lagrange", 1)))
    assert max(reference.successive_differences(w, fine).values()) < 1e-13
    assert reference.successive_differences(v, fine)["diff_H1"] == pytest.approx(direct["H1"], rel=1e-12)


def test_reference_errors_exact_serial(make_config):
    check_reference_errors_exact(make_config, MPI.COMM_SELF)


@pytest.mark.mpi
def test_reference_errors_exact_two_ranks(make_config):
    assert MPI.COMM_WORLD.size == 2
    check_reference_errors_exact(make_config, MPI.COMM_WORLD)


def test_data_only_scene_columns_and_cache(make_config):
    cfg = make_config(epsilon={"law": "constant", "theta": 0.1}, mesh={"refinements": [4, 8, 16]}, **DATA_ONLY)
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    extra = levels[-1].extra
    assert [c for c in extra if c not in stability.SOLVER_COLUMNS + ("contact_quadrature",)][:4] == ["L2_ref", "rate_L2_ref", "H1_ref",
                                                                         "rate_H1_ref"]
    assert {"diff_L2", "rate_diff_H1", "penetration", "contact_measure", "contact_force", "energy"} <= set(extra)
    assert not {"L2", "H1"} & set(levels[0].errors)  # no exact solution, no exact-error columns
    assert levels[0].extra["diff_L2"] is None and extra["rate_diff_L2"] is not None
    # constant eps: one reference solve (N = 32), reused by the later levels
    assert levels[0].extra["reference_time_s"] > 0 and extra["reference_time_s"] == 0.0
    # f = 10 pushes u > 0 into the whole contact face: penetration and the full face in contact
    assert extra["penetration"] > 0 and extra["contact_measure"] == pytest.approx(1.0)


def test_fixed_equals_per_level_for_constant_eps(make_config):
    def errors(mode):
        cfg = make_config(epsilon={"law": "constant", "theta": 0.1}, mesh={"refinements": [4, 8]},
                          verification={"reference_epsilon": mode}, **DATA_ONLY)
        return [lv.errors for lv in studies.run_study(cfg, comm=MPI.COMM_SELF)]
    assert errors("fixed") == errors("per_level")  # the same eps: the same reference, bit for bit


def data_only_config(tmp_path):
    cfg = config.load(ROOT / "configs/paper/data-push-theta-h.yaml")
    return config.loads(cfg.text, ["mesh.refinements=[8, 16, 32]", f"output.dir={tmp_path}"])


@pytest.mark.mpi
def test_data_only_scene_two_ranks_match_one(tmp_path):
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    cfg = data_only_config(tmp_path)
    parallel = studies.run_study(cfg, comm=comm)
    serial = studies.run_study(cfg, comm=MPI.COMM_SELF)  # every rank solves the whole scene alone
    for p, s in zip(parallel, serial):
        assert p.outcome.converged and s.outcome.converged
        assert set(p.errors) == set(s.errors) and list(p.extra) == list(s.extra)
        for name, value in p.errors.items():
            assert value == pytest.approx(s.errors[name], rel=RTOL), name
        # the solver's own diagnostics (the last Newton correction: ~1e-15 ||u_h|| after the polish) follow
        # the partition's round-off; the measured columns must not
        for name, value in p.extra.items():
            if value is not None and not name.endswith("time_s") and name not in stability.SOLVER_COLUMNS:
                assert value == pytest.approx(s.extra[name], rel=RTOL), name
