"""The elastic problem: its config keys and bad input, the contact term on a vector space against UFL,
the facet normals, and the rigid motions AMG is given."""
from pathlib import Path

import numpy as np
import pytest
import ufl
import yaml
from mpi4py import MPI

from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from signorini_cli import config
from signorini_cli.app import cli
from signorini_cli.meshing import meshes
from signorini_cli.problems import contact, elasticity
from conftest import BASE, assembled_beside_ufl, merge

EXACT_2D = ["0.1*sin(pi*x)*y", "0.1*cos(2*pi*x)*(1 - y)**2"]
EXACT_3D = ["0.1*sin(pi*x)*z", "0.1*sin(pi*y)*z", "0.1*cos(2*pi*x)*cos(2*pi*y)*(1 - z)**2"]
ELASTIC = {"problem": {"pde": "elasticity", "exact": EXACT_2D}, "material": {"E": 1.0, "nu": 0.3}}
CUBE = {"dimension": 3, "mesh": {"kind": "unit_cube", "refinements": [2, 4]},
        "problem": {"pde": "elasticity", "exact": EXACT_3D}, "material": {"E": 1.0, "nu": 0.3}}


def elastic_config(tmp_path, dim=2, **changes):
    scene = ELASTIC if dim == 2 else merge(ELASTIC, CUBE)
    raw = merge(merge(BASE, scene), dict(changes, output={"dir": str(tmp_path)}))
    return config.loads(yaml.safe_dump(raw))


# --- config: the keys and one line naming the bad key -------------------------------------------------

def test_elastic_config_reads_components_material_gap(tmp_path):
    cfg = elastic_config(tmp_path, problem={"gap": "0.01*x", "normal": [0, -2]}, material={"E": 200.0, "nu": 0.25})
    assert cfg.problem.pde == "elasticity" and len(cfg.problem.exact) == 2
    assert (cfg.material.E, cfg.material.nu) == (200.0, 0.25)
    assert cfg.problem.normal == (0.0, -1.0)  # normalised


@pytest.mark.fast
@pytest.mark.parametrize("name", ("square-alpha2.yaml", "hertz.yaml"))
def test_elastic_config_round_trips(name):
    """to_dict writes what from_dict reads back to the same settings (resume and `signorini init` rely on it)."""
    cfg = config.load(Path(__file__).resolve().parents[2] / "configs" / "elasticity" / name)
    assert config.fingerprint(config.from_dict(config.to_dict(cfg))) == config.fingerprint(cfg)


BAD = [
    pytest.param({"problem": {"exact": EXACT_2D[:1]}}, "problem.exact: must be a list of 2 expressions",
                 id="one-component"),
    pytest.param({"problem": {"exact": EXACT_3D}}, "problem.exact: must be a list of 2 expressions", id="three-in-2d"),
    pytest.param({"problem": {"exact": "x*y"}}, "problem.exact: must be a list of 2 expressions", id="scalar-string"),
    pytest.param({"problem": {"exact": ["x", "q"]}}, "problem.exact[1]:", id="bad-component"),
    pytest.param({"material": {"E": 0}}, "material.E: must be > 0, got 0", id="E-zero"),
    pytest.param({"material": {"E": -1.0}}, "material.E: must be > 0, got -1", id="E-negative"),
    pytest.param({"material": {"nu": 0.5}}, "material.nu: must be in (-1, 0.5)", id="nu-incompressible"),
    pytest.param({"material": {"nu": -1.0}}, "material.nu: must be in (-1, 0.5)", id="nu-minus-one"),
    pytest.param({"material": {"rho": 1.0}}, "material.rho: unknown key in material", id="material-unknown"),
    pytest.param({"problem": {"f": "1"}}, "problem.f: only meaningful with problem.pde: poisson", id="f-on-elastic"),
    pytest.param({"problem": {"exact_solves": "signorini"}}, "problem.exact_solves: only meaningful with problem.pde: poisson",
                 id="exact-solves-on-elastic"),
    pytest.param({"problem": {"normal": [0, 0]}}, "problem.normal: must not be zero", id="normal-zero"),
    pytest.param({"problem": {"pde": "stokes"}}, "problem.pde: 'stokes' is not one of poisson, elasticity", id="pde"),
    pytest.param({"study_type": "signorini", "alpha": None, "epsilon": None},
                 "problem.exact: study_type signorini with pde: elasticity solves the physical problem",
                 id="vi-with-exact"),
    pytest.param({"study_type": "total_error", "problem": {"exact": None, "gap": "x - 1"}, "alpha": None,
                  "epsilon": None, "limit": {"alpha": [1], "exponent": [1]}},
                 "study_type: total_error measures u_S − u_h: pde: elasticity has no manufactured",
                 id="total-elastic"),
    pytest.param({"study_type": "total_error", "alpha": None, "epsilon": None,
                  "limit": {"alpha": [1], "exponent": [1]}},
                 "study_type: total_error measures u_S − u_h: pde: elasticity has no manufactured",
                 id="total-elastic-exact"),
    pytest.param({"study_type": "signorini", "problem": {"exact": None, "gap": "x - 1", "normal": [1, 0]},
                  "alpha": None, "epsilon": None}, "problem.normal: study_type signorini bounds u·n on the face's "
                 "own normal [0.0, -1.0]", id="vi-other-normal"),
    pytest.param({"problem": {"hertz_radius": 1.0}}, "problem.hertz_radius: a Hertz contact is the physical "
                 "problem", id="hertz-manufactured"),
    pytest.param({"problem": {"exact": None, "hertz_radius": 0}}, "problem.hertz_radius: must be > 0",
                 id="hertz-radius"),
    pytest.param({"problem": {"exact": None}, "verification": {"measures": ["hertz"]}},
                 "verification.measures[0]: hertz needs problem.hertz_radius", id="hertz-measure"),
]
SCALAR_BAD = [
    pytest.param({"material": {"E": 1.0}}, "material: only meaningful with problem.pde: elasticity", id="material"),
    pytest.param({"problem": {"gap": "0"}}, "problem.gap: only meaningful with problem.pde: elasticity", id="gap"),
    pytest.param({"problem": {"normal": [0, -1]}}, "problem.normal: only meaningful with problem.pde: elasticity",
                 id="normal"),
    pytest.param({"problem": {"hertz_radius": 1.0}},
                 "problem.hertz_radius: only meaningful with problem.pde: elasticity", id="hertz"),
    pytest.param({"verification": {"measures": ["hertz"]}}, "verification.measures[0]: hertz measures an elastic",
                 id="hertz-measure"),
]


def run_bad(tmp_path, capsys, raw):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    code = cli.main(["run", str(path), "--output", str(tmp_path / "out")])
    err = capsys.readouterr().err
    return code, err


@pytest.mark.fast
@pytest.mark.parametrize("changes, message", BAD)
def test_bad_elastic_input_exits_2_one_line(tmp_path, capsys, changes, message):
    code, err = run_bad(tmp_path, capsys, merge(merge(BASE, ELASTIC), changes))
    assert code == cli.EXIT_BAD_INPUT
    assert err.count("\n") == 1 and err.startswith(f"signorini: error: {tmp_path / 'bad.yaml'}: {message}"), err


@pytest.mark.fast
@pytest.mark.parametrize("changes, message", SCALAR_BAD)
def test_elastic_keys_on_scalar_problem_exit_2(tmp_path, capsys, changes, message):
    code, err = run_bad(tmp_path, capsys, merge(BASE, changes))
    assert code == cli.EXIT_BAD_INPUT
    assert err.count("\n") == 1 and err.startswith(f"signorini: error: {tmp_path / 'bad.yaml'}: {message}"), err


@pytest.mark.fast
def test_component_count_3d(tmp_path, capsys):
    code, err = run_bad(tmp_path, capsys, merge(merge(BASE, CUBE), {"problem": {"exact": EXACT_2D}}))
    assert code == cli.EXIT_BAD_INPUT and "problem.exact: must be a list of 3 expressions" in err


# --- the discrete pieces ------------------------------------------------------------------------------

def level(cfg, n):
    domain = meshes.build(cfg.mesh, cfg.contact, n, MPI.COMM_WORLD)
    V = elasticity.space(cfg, domain.mesh)
    return domain, V, fem.Function(V)


@pytest.mark.parametrize("dim", (2, 3))
def test_facet_normals_bottom_face(tmp_path, dim):
    cfg = elastic_config(tmp_path, dim)
    domain, _, _ = level(cfg, 4)
    n = elasticity.facet_normals(domain.mesh, elasticity.owned_contact_facets(domain))
    expected = np.zeros(dim)
    expected[-1] = -1.0  # the bottom face's outward normal
    assert np.abs(n - expected).max(initial=0.0) < 1e-14  # round-off of unit-length arithmetic


@pytest.mark.parametrize("alpha", (2.0, 3.0))
@pytest.mark.parametrize("dim", (2, 3, pytest.param(2, marks=pytest.mark.mpi, id="2-mpi"),
                                 pytest.param(3, marks=pytest.mark.mpi, id="3-mpi")))
def test_vector_contact_term_equals_ufl_where_polynomial(tmp_path, dim, alpha):
    """With w_h = u_h·n − g0 > 0 on all of Γ_C, [w_h]_+^alpha v·n is a polynomial of degree alpha + 1 on
    each facet for integer alpha: UFL's Gauss rule of that degree is exact, so residual and Jacobian of
    the term beside UFL must equal UFL's assembly to round-off."""
    cfg = elastic_config(tmp_path, dim, alpha=alpha, problem={"gap": "-0.5 + 0.1*x"})
    domain, V, u_h = level(cfg, 4)
    rng = np.random.default_rng(3)
    u_h.x.array[:] = 0.1 * rng.random(u_h.x.array.size)  # |u| < 0.2 and -g0 >= 0.4: w_h > 0
    u_h.x.scatter_forward()
    eps = fem.Constant(domain.mesh, 0.5)
    term = elasticity.contact_term(cfg, domain, u_h, eps, penalty=True, kinked=False)
    n = ufl.FacetNormal(domain.mesh)
    x = ufl.SpatialCoordinate(domain.mesh)
    v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
    w_h = ufl.dot(u_h, n) - (-0.5 + 0.1 * x[0])
    F = w_h ** int(alpha) / eps * ufl.dot(v, n) * domain.ds_c(int(alpha) + 1)
    b, b_ufl, A, A_ufl = assembled_beside_ufl(term, F, ufl.derivative(F, u_h, du), u_h)
    # round-off: sums of a few hundred terms of size <= 1 (1e-13 of the largest entry)
    assert abs(b.norm() - b_ufl.norm()) <= 1e-13 * b_ufl.norm()
    b.axpy(-1.0, b_ufl)
    assert b.norm() <= 1e-13 * b_ufl.norm()
    A.axpy(-1.0, A_ufl)
    assert A.norm() <= 1e-13 * A_ufl.norm()


@pytest.mark.parametrize("dim", (2, 3))
def test_rigid_motions_span_the_stiffness_kernel(tmp_path, dim):
    """K z = 0 for every rigid motion z (no boundary conditions): 3 modes in 2-D, 6 in 3-D."""
    cfg = elastic_config(tmp_path, dim)
    domain, V, _ = level(cfg, 4)
    mu, lmbda = elasticity.lame(cfg.material)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    K = fem_petsc.assemble_matrix(fem.form(ufl.inner(elasticity.sigma(u, mu, lmbda), elasticity.strain(v)) * ufl.dx))
    K.assemble()
    modes = elasticity.rigid_motions(V).getVecs()
    assert len(modes) == 3 * (dim - 1)
    Kz = K.createVecLeft()
    for z in modes:
        K.mult(z, Kz)
        assert Kz.norm() <= 1e-12 * K.norm()  # round-off: the modes are orthonormal, K's rows sum to zero


@pytest.mark.mpi
def test_rigid_motions_live_on_the_mesh_communicator():
    """On 2 ranks, a one-rank mesh's near-nullspace is a one-rank object: made on PETSc's default
    communicator (COMM_WORLD) it was freed on that rank alone, and PETSc's finalize then waited forever."""
    cfg = config.loads(yaml.safe_dump(BASE))
    domain = meshes.build(cfg.mesh, cfg.contact, 4, MPI.COMM_SELF)
    V = fem.VectorFunctionSpace(domain.mesh, ("Lagrange", 1))
    assert elasticity.rigid_motions(V).getComm().getSize() == 1


def test_lame_plane_strain():
    """μ = E/(2(1+ν)), λ = Eν/((1+ν)(1−2ν)): E = 2.6, ν = 0.3 give μ = 1, λ = 1.5."""
    mu, lmbda = elasticity.lame(config.pde_elasticity.Material(E=2.6, nu=0.3))
    assert mu == pytest.approx(1.0, rel=1e-15) and lmbda == pytest.approx(1.5, rel=1e-15)


def test_contact_term_scalar_rows_unchanged(tmp_path):
    """On a scalar space the term's rows are its dofs (the scalar problem's path is untouched)."""
    cfg = config.loads(yaml.safe_dump(merge(BASE, {"output": {"dir": str(tmp_path)}})))
    domain = meshes.build(cfg.mesh, cfg.contact, 4, MPI.COMM_WORLD)
    V = fem.FunctionSpace(domain.mesh, ("Lagrange", 1))
    term = contact.ContactTerm(fem.Function(V), domain.facet_tags, meshes.CONTACT, 2.0, fem.Constant(domain.mesh, 1.0))
    assert np.array_equal(term.rows, term.dofs)
