"""Nitsche's contact term beside UFL: against UFL's assembly where [u_h − γ∂_n u_h]_+ has no kink (a
polynomial), its Jacobian against differences of its residual where it kinks, a closed-form case, and the
Γ_C geometry (outward normal derivatives, cell diameters) against UFL's."""
import numpy as np
import pytest
import ufl
import yaml
from mpi4py import MPI

from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from signorini_cli import config, studies
from signorini_cli.app import cli
from signorini_cli.meshing import meshes
from signorini_cli.problems import nitsche
from signorini_cli.studies import refinement
from conftest import BASE, U_SIGNORINI, assembled_beside_ufl, merge

THETAS = (1.0, 0.0, -1.0)
DIMS = (2, 3, pytest.param(2, marks=pytest.mark.mpi, id="2-mpi"), pytest.param(3, marks=pytest.mark.mpi, id="3-mpi"))


@pytest.fixture
def level(make_config):
    """level(dim, n): the unit square or cube with Γ_C its bottom face, n cells per side, and a P1 u_h."""
    def make(dim, n):
        cfg = make_config(dimension=dim, mesh={"kind": "unit_square" if dim == 2 else "unit_cube"})
        domain = meshes.build(cfg.mesh, cfg.contact, n, MPI.COMM_WORLD)
        return domain, fem.Function(fem.FunctionSpace(domain.mesh, ("Lagrange", 1)))
    return make


def set_u(u_h, values):
    u_h.interpolate(values)
    u_h.x.scatter_forward()


def ufl_forms(u_h, domain, theta, gamma0):
    """(F, J) of the Nitsche term in UFL without its positive part, with a Gauss rule exact for it (P1:
    P = u − γ∂_n u linear on a facet, times v or ∂_n v: degree 2)."""
    msh = domain.mesh
    v, du = ufl.TestFunction(u_h.function_space), ufl.TrialFunction(u_h.function_space)
    n = ufl.FacetNormal(msh)
    gamma = gamma0 * ufl.CellDiameter(msh)
    ds_c = domain.ds_c(2)
    P = u_h - gamma * ufl.dot(ufl.grad(u_h), n)
    F = P / gamma * (v - theta * gamma * ufl.dot(ufl.grad(v), n)) * ds_c
    return F, ufl.derivative(F, u_h, du)


@pytest.mark.parametrize("theta", THETAS)
@pytest.mark.parametrize("dim", DIMS)
def test_nitsche_term_equals_ufl_without_kink(level, dim, theta):
    """With P = u_h − γ∂_n u_h > 0 on all of Γ_C the term is a polynomial UFL integrates exactly: residual
    and (for θ ≠ 1 non-symmetric) Jacobian equal UFL's to round-off."""
    domain, u_h = level(dim, 4)
    rng = np.random.default_rng(1)
    set_u(u_h, lambda x: 1.0 + 0.1 * x[0] + 0.05 * x[1])
    u_h.x.array[:] += 0.01 * rng.random(u_h.x.array.size)  # |γ∂_n u| <= 0.1: P >= 0.8
    u_h.x.scatter_forward()
    term = nitsche.NitscheTerm(u_h, domain, theta, 0.1)
    b, b_ufl, A, A_ufl = assembled_beside_ufl(term, *ufl_forms(u_h, domain, theta, 0.1), u_h)
    # round-off: sums of a few terms of size <= 1/γ ~ 30 (1e-13 of the largest entry)
    b.axpy(-1.0, b_ufl)
    assert b.norm() <= 1e-13 * b_ufl.norm()
    A.axpy(-1.0, A_ufl)
    assert A.norm() <= 1e-13 * A_ufl.norm()


@pytest.mark.parametrize("theta", THETAS)
@pytest.mark.parametrize("dim", (2, 3))
def test_nitsche_jacobian_is_the_residuals_derivative(level, dim, theta):
    """Where [P]_+ kinks inside facets, J v equals the central difference of the residual along v (the
    residual is C^1 in u: its second difference is O(δ²) with constants ~ 1/γ, here below 1e-6)."""
    domain, u_h = level(dim, 4)
    set_u(u_h, lambda x: np.sin(5 * x[0]) * 0.3 + x[1] - 0.1)
    term = nitsche.NitscheTerm(u_h, domain, theta, 0.5)
    u = u_h.x.array.copy()
    assert (term.argument(u) > 0).any() and (term.argument(u) < 0).any()  # kinks inside facets
    direction = np.random.default_rng(2).random(u.size)
    delta = 1e-6
    difference = (term.residual(u + delta * direction) - term.residual(u - delta * direction)) / (2 * delta)
    along = np.einsum("fjk,fk->fj", term.jacobian(u), direction[term.rows])
    assert np.abs(difference - along).max() <= 1e-6 * np.abs(along).max()


def test_nitsche_residual_closed_form(level):
    """u_h = x − 0.3 on the unit square (N = 4): ∂_n u_h = 0 on y = 0, so P = x − 0.3 and the residual
    against v = 1 is (1/γ)∫_0^1 [x − 0.3]_+ dx = 0.245/γ, γ = γ0 √2/4 (every cell's diameter), whatever θ
    (Σ_j ∂_n φ_j = ∂_n 1 = 0)."""
    domain, u_h = level(2, 4)
    set_u(u_h, lambda x: x[0] - 0.3)
    for theta in THETAS:
        term = nitsche.NitscheTerm(u_h, domain, theta, 0.5)
        total = domain.mesh.comm.allreduce(term.residual(u_h.x.array).sum(), op=MPI.SUM)
        assert total == pytest.approx(0.245 / (0.5 * np.sqrt(2) / 4), rel=1e-14)
        assert term.contact_force() == pytest.approx(0.245 / (0.5 * np.sqrt(2) / 4), rel=1e-14)
        assert term.contact_measure() == pytest.approx(0.7, rel=1e-14)


@pytest.mark.parametrize("dim", (2, 3))
def test_cell_geometry_matches_ufl(level, dim):
    """∂_n φ_j and h_K per Γ_C facet equal UFL's grad(φ)·n and CellDiameter (integrated over the facet)."""
    domain, u_h = level(dim, 3)
    V = u_h.function_space
    term = nitsche.NitscheTerm(u_h, domain, 1.0, 1.0)
    v = ufl.TestFunction(V)
    n = ufl.FacetNormal(domain.mesh)
    flux = fem_petsc.assemble_vector(fem.form(ufl.dot(ufl.grad(v), n) * domain.ds_c(0)))
    flux.ghostUpdate(addv=2, mode=1)
    mine = fem_petsc.create_vector(fem.form(v * domain.ds_c(0)))
    with mine.localForm() as local:
        local.set(0.0)
        np.add.at(local.array_w, term.rows, term.sizes[:, None] * term.flux)
    mine.ghostUpdate(addv=2, mode=1)
    mine.axpy(-1.0, flux)
    assert mine.norm() <= 1e-13 * flux.norm()
    h_ufl = domain.mesh.comm.allreduce(fem.assemble_scalar(fem.form(ufl.CellDiameter(domain.mesh) * domain.ds_c(0))),
                                       op=MPI.SUM)
    h_mine = domain.mesh.comm.allreduce(float(np.sum(term.sizes * term.gamma)), op=MPI.SUM)
    assert h_mine == pytest.approx(h_ufl, rel=1e-14)


# --- the method in studies: rates, verdicts, 2 ranks, config -------------------------------------------

def nitsche_config(theta, dim=2, **changes):
    """Nitsche's method on the manufactured Signorini solution u_S (contact x < 1/2 on y = 0, resp. z = 0)."""
    exact = U_SIGNORINI if dim == 2 else U_SIGNORINI.replace("y", "z")
    raw = merge(BASE, {"alpha": None, "epsilon": None, "dimension": dim,
                       "mesh": {"kind": "unit_square" if dim == 2 else "unit_cube", "refinements": [8, 16, 32]},
                       "problem": {"exact": exact, "exact_solves": "signorini", "method": "nitsche"},
                       "nitsche": {"theta": theta, "gamma0": 0.1}, "solver": {"linear": "direct"}})
    return config.loads(yaml.safe_dump(merge(raw, changes)))


@pytest.mark.parametrize("theta", THETAS)
def test_nitsche_study_h1_rate_and_verdict(theta):
    """N = 8, 16, 32 on u_S: H1 rates 0.99, 1.00 (θ = 1, 0, -1 alike, measured); the proven O(h) agrees."""
    cfg = nitsche_config(theta)
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)
    assert all(lv.eps == 0.0 for lv in levels)  # no ε: recorded as the VI's
    h1 = [lv.errors["H1"] for lv in levels]
    assert np.log(h1[-2] / h1[-1]) / np.log(levels[-2].h / levels[-1].h) >= 1.0 - 0.05  # 0.05: measured 0.99+
    summary = refinement.summary(cfg, levels)
    h1_verdict = next(v for v in summary.norms if v.norm == "H1")
    assert (h1_verdict.proven, h1_verdict.verdict) == (1.0, "agrees")
    assert {v.norm: v.verdict for v in summary.norms}["L2"] == "not covered"
    assert set(levels[-1].extra) >= {"L2_gc", "penetration", "contact_measure"}
    assert "energy_err" not in levels[-1].extra and "pos_gc" not in levels[-1].extra


@pytest.mark.mpi
@pytest.mark.parametrize("theta", THETAS)
def test_nitsche_two_ranks_match_one(theta):
    """The same study on 2 ranks and on one: errors and Γ_C quantities to 1e-8 (the solver's tolerance)."""
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    cfg = nitsche_config(theta, verification={"measures": ["L2_gc", "penetration", "contact_measure",
                                                             "contact_force"]})
    parallel = studies.run_study(cfg, comm=comm)
    serial = studies.run_study(cfg, comm=MPI.COMM_SELF)
    for p, s in zip(parallel, serial):
        assert p.outcome.converged and s.outcome.converged
        for norm in ("L2", "H1", "L2_gc"):
            assert p.errors[norm] == pytest.approx(s.errors[norm], rel=1e-8)
        for name in ("penetration", "contact_measure", "contact_force"):
            assert p.extra[name] == pytest.approx(s.extra[name], rel=1e-8)


def test_nitsche_3d_converges_at_rate_one():
    """The cube, N = 4, 8: the H1 rate of the last pair is 0.96 (measured; 0.1 = pre-asymptotic margin)."""
    cfg = nitsche_config(1.0, dim=3, mesh={"refinements": [4, 8]})
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    assert all(lv.outcome.converged for lv in levels)
    h1 = [lv.errors["H1"] for lv in levels]
    assert np.log(h1[0] / h1[1]) / np.log(levels[0].h / levels[1].h) >= 1.0 - 0.1


BAD = [
    pytest.param({"alpha": 2.0}, "alpha: not used by problem.method nitsche (nitsche has no ε and no α)", id="alpha"),
    pytest.param({"epsilon": {"law": "theta_h"}}, "epsilon: not used by problem.method nitsche", id="epsilon"),
    pytest.param({"nitsche": {"theta": 0.5}}, "nitsche.theta: must be 1, 0 or -1, got 0.5", id="theta"),
    pytest.param({"nitsche": {"gamma0": 0}}, "nitsche.gamma0: must be > 0", id="gamma0"),
    pytest.param({"problem": {"exact_solves": "compliance"}}, "problem.exact_solves: nitsche discretises the "
                 "Signorini problem", id="compliance-solution"),
    pytest.param({"solver": {"linear": "auto"}, "nitsche": {"theta": 0}}, "solver.linear: nitsche.theta 0 makes "
                 "the Jacobian non-symmetric", id="cg"),
    pytest.param({"verification": {"measures": ["energy_err"]}}, "verification.measures[0]: nitsche measures",
                 id="energy-err"),
    pytest.param({"study_type": "signorini"}, "problem.method: nitsche is solved by refinement studies",
                 id="vi-study"),
    pytest.param({"element": {"degree": 2}}, "element.degree: nitsche is built for P1", id="p2"),
]


@pytest.mark.fast
@pytest.mark.parametrize("changes, message", BAD)
def test_nitsche_config_refuses(tmp_path, capsys, changes, message):
    """Each bad key ends as exit 2 with one line naming it."""
    base = merge(BASE, {"alpha": None, "epsilon": None, "nitsche": {"theta": 1, "gamma0": 0.1},
                        "problem": {"exact": U_SIGNORINI, "exact_solves": "signorini", "method": "nitsche"},
                        "solver": {"linear": "direct"}})
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(base, changes)))
    assert cli.main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("signorini: error: ") and message in err[0]


def test_nitsche_section_refused_with_penalty(make_config):
    with pytest.raises(config.ConfigError, match="nitsche: only meaningful with problem.method: nitsche"):
        make_config(nitsche={"theta": 1})


def test_nitsche_data_only_references_and_quantities():
    """f alone (f = 10 sin(πx) presses all of Γ_C into contact): errors against references one refinement finer
    and successive differences fall at the proven H1 rate, and the quantities get a grid-convergence
    estimate (no ε changes with h: measured order 1.75 for the contact force)."""
    cfg = nitsche_config(-1.0, problem={"exact": None, "exact_solves": None, "f": "10*sin(pi*x)"},
                         verification={"reference_refinements": 1})
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    summary = refinement.summary(cfg, levels)
    found = {v.norm: v for v in summary.norms}
    assert found["H1_ref"].verdict == "agrees"  # measured 0.99 in [0.97, 1.02]
    assert found["diff_H1"].proven == 1.0  # two differences of three levels: too few to fit, but covered
    force = next(q for q in summary.quantities if q.quantity == "contact_force")
    assert force.estimate is not None and force.estimate.order > 1.0  # 1.0: below the measured 1.75
