"""Problems refused before solving: data nan or infinite where the solve evaluates them, and a
manufactured Signorini solution that violates u_S <= 0, ∂_n u_S <= 0, u_S ∂_n u_S = 0 on Γ_C."""
import re
import warnings

import pytest
import yaml
from mpi4py import MPI

from dolfinx import fem
from signorini_cli.app import cli
from signorini_cli.config import ConfigError
from signorini_cli.meshing import meshes
from signorini_cli.problems import compliance, posed
from conftest import BASE, U_SIGNORINI, merge


def check(make_config, comm, **changes):
    cfg = make_config(**changes)
    domain = meshes.build(cfg.mesh, cfg.contact, 8, comm)
    eps = fem.Constant(domain.mesh, 0.1)
    posed.check(cfg, domain, compliance.exact_solution(cfg, domain.mesh, eps), 0.1, coarsest=domain)


@pytest.mark.parametrize("problem, message", [
    pytest.param({"exact": "sqrt(x-0.5)*y"}, r"^problem.exact: sqrt\(x-0.5\)\*y is nan at \(", id="exact-nan"),
    pytest.param({"exact": "x*log(x + y)"}, r"^problem.exact: x\*log\(x \+ y\) is nan at \(0, 0\)",
                 id="exact-at-corner"),
    pytest.param({"exact": None, "f": "sqrt(0.5 - x)"}, r"^problem.f: sqrt\(0.5 - x\) is nan at \(", id="data-f"),
    pytest.param({"exact": "sin(2*pi*x)*(1-y)**2", "exact_solves": "signorini"},
                 r"^problem.exact: not a Signorini solution: u_S > 0 on Γ_C, worst at \(0.25, 0\)", id="u_S-positive"),
    pytest.param({"exact": "-x*(1+y)**2", "exact_solves": "signorini"},
                 r"^problem.exact: not a Signorini solution: ∂_n u_S > 0 on Γ_C", id="u_S-pulls"),
    # f ~ r^-4/3 at the corner: its load changes by 2.4e-2 between the degrees 16 and 20
    pytest.param({"define": {"r": "sqrt(x**2 + y**2)"}, "exact": "r**(2/3)*(1-y)"},
                 r"^problem.exact: the load of f = -Δ\(r\*\*\(2/3\)\*\(1-y\)\) does not settle"
                 r".* \(most near \(0, 0\)\)",
                 id="unbounded-f-at-a-vertex"),
])
def test_refused_before_solving(make_config, problem, message):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no numpy RuntimeWarning on the way: the message says it all
        with pytest.raises(ConfigError, match=message):
            check(make_config, MPI.COMM_SELF, problem=problem)


@pytest.mark.parametrize("problem", [
    pytest.param({"exact": U_SIGNORINI, "exact_solves": "signorini"}, id="signorini-solution"),
    # harmonic: f = 0 up to round-off, though ∇u_ex is unbounded at the corner (the L-shape's solution)
    pytest.param({"define": {"r": "sqrt(x**2 + y**2)", "t": "atan2(y, x)"}, "exact": "r**(2/3)*sin(2*t/3)"},
                 id="harmonic-singular-gradient-at-vertex"),
])
def test_posed_right_passes(make_config, problem):
    check(make_config, MPI.COMM_SELF, problem=problem)


@pytest.mark.mpi
def test_refused_on_every_rank(make_config):
    assert MPI.COMM_WORLD.size == 2
    with pytest.raises(ConfigError, match="not a Signorini solution"):
        check(make_config, MPI.COMM_WORLD, problem={"exact": "sin(2*pi*x)*(1-y)**2", "exact_solves": "signorini"})


def test_cli_exit_2_one_line(tmp_path, capsys):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, {"problem": {"exact": "sqrt(x-0.5)*y"},
                                                "output": {"dir": str(tmp_path / "out")}})))
    assert cli.main(["run", str(path)]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"signorini: error: {path}: problem.exact: sqrt(x-0.5)*y is nan at")


@pytest.mark.fast
def test_checked_once_per_mesh_family_and_data(make_config, monkeypatch):
    """Within registry.checked_once() (a study, a map) the data are checked at the cells' points (of the
    family's coarsest mesh) once per mesh family, again for other data or another ε when the data use eps
    (the vertices on every level); a refusal is never remembered as a pass."""
    from signorini_cli.problems import registry
    calls = []
    monkeypatch.setitem(registry.POSED, "poisson", lambda cfg, domain, *rest, coarsest: calls.append(
        coarsest is not None) or posed.check(cfg, domain, *rest, coarsest=coarsest))
    plain, with_eps = make_config(), make_config(problem={"exact": "sin(2*pi*x)*(1-y)**2 + eps*x*y"})
    defined = [make_config(problem={"define": {"s": "sin(2*pi*x)"}, "exact": "s*(1-y)**2"}) for _ in range(2)]
    bad = make_config(problem={"exact": None, "f": "sqrt(0.5 - x)"})
    crossed = make_config(mesh={"diagonal": "crossed"})
    domain, other = (meshes.build(plain.mesh, plain.contact, n, MPI.COMM_SELF) for n in (4, 8))

    def check_on(cfg, on, eps_value=0.1):
        registry.check_posed(cfg, on, compliance.exact_solution(cfg, on.mesh, fem.Constant(on.mesh, eps_value)),
                             eps_value)
    with registry.checked_once():
        for cfg, on, eps_value in [(plain, domain, 0.1), (plain, domain, 0.2), (plain, other, 0.1),
                                   (with_eps, domain, 0.1), (with_eps, other, 0.1), (with_eps, domain, 0.2)]:
            check_on(cfg, on, eps_value)
        # plain once for the family whatever the mesh and ε, with_eps at each of its two ε
        assert calls == [True, False, False, True, False, True]
        for cfg in defined:  # the same definitions, parsed twice (as two points of a map are)
            check_on(cfg, domain)
        assert calls[-2:] == [True, False]
        check_on(crossed, domain)  # another family
        assert calls[-1] is True
        for _ in range(2):
            with pytest.raises(ConfigError, match="is nan at"):
                check_on(bad, domain)


@pytest.mark.fast
def test_cells_checked_on_a_coarse_member_of_a_built_in_family(make_config, monkeypatch):
    """The cells' checks and the Profile run on a built-in family's coarsest level, at most N = CHECK_N (here
    4 in 2-D): a study from N = 8 takes them on N = 4, whose h the Profile scales from; one from N = 2 on N = 2."""
    from signorini_cli.problems import registry
    monkeypatch.setitem(registry.CHECK_N, 2, 4)
    checked = []
    monkeypatch.setitem(registry.POSED, "poisson", lambda cfg, domain, *rest, coarsest: checked.append(
        coarsest.n) or posed.check(cfg, domain, *rest, coarsest=coarsest))
    for levels, expect in (([8, 16], 4), ([2, 4], 2)):
        cfg = make_config(mesh={"refinements": levels})
        domain = meshes.build(cfg.mesh, cfg.contact, levels[0], MPI.COMM_SELF)
        eps_value = cfg.epsilon(domain.h)
        with registry.checked_once():
            registry.check_posed(cfg, domain, compliance.exact_solution(
                cfg, domain.mesh, fem.Constant(domain.mesh, eps_value)), eps_value)
        assert checked[-1] == expect


@pytest.mark.parametrize("changes, message", [
    pytest.param({"problem": {"pde": "elasticity", "exact": ["sqrt(x-0.5)", "0"]}, "material": {"E": 1.0, "nu": 0.3}},
                 r"problem.exact: sqrt\(x-0.5\) is nan at \(", id="elastic-nan"),
    pytest.param({"study_type": "signorini", "alpha": None, "epsilon": None,
                  "problem": {"exact": "sin(2*pi*x)*(1-y)**2", "exact_solves": "signorini"}},
                 r"problem.exact: not a Signorini solution: u_S > 0 on Γ_C", id="signorini-study-u_S-positive"),
    # f = -Δu_ex unbounded along x = 0.3: a degree-6 load made the L2 error at N = 128 88 times the true one
    pytest.param({"mesh": {"refinements": [8, 16, 32, 64, 128]},
                  "problem": {"exact": "(abs(x-0.3)**1.5 - 0.1)*(1-y)**2"}},
                 r"problem.exact: the load of f = -Δ\(\(abs\(x-0.3\)\*\*1.5 - 0.1\)\*\(1-y\)\*\*2\) does not "
                 r"settle: quadrature degree 16 -> 20 changes it by .* relative \(most near \(0.[23]\d*, ",
                 id="unbounded-f"),
    pytest.param({"problem": {"exact": None, "f": "1/sqrt(abs(x-0.3))"}},
                 r"problem.f: the load of 1/sqrt\(abs\(x-0.3\)\) does not settle", id="unbounded-data-only-f"),
])
def test_every_study_type_refuses_before_solving(tmp_path, capsys, changes, message):
    """Elasticity (else DIVERGED_FNORM_NAN) and the VI's study type (else solved and reported, rates near 0)
    check their problem too: exit 2, one line."""
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(merge(BASE, {"output": {"dir": str(tmp_path / "out")}}), changes)))
    assert cli.main(["run", str(path)]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"signorini: error: {path}: ")
    assert re.search(message, err)


def test_quadrature_from_the_data_as_with_degree_16(make_config, monkeypatch):
    """Elastic 3-D, N = 2, 4, 8: the degrees chosen from the data give the L2 and H1 errors of every quadrature
    degree raised to 16 within 1e-8 relative (degree 6 for the data, 8 for the errors were 1.4e-4 off at N = 2;
    observed now <= 4e-13)."""
    from signorini_cli import studies
    from signorini_cli.problems import element
    cfg = make_config(dimension=3, mesh={"kind": "unit_cube", "refinements": [2, 4, 8]}, problem={
        "pde": "elasticity", "exact": ["0.1*sin(pi*x)*z", "0.1*sin(pi*y)*z", "0.1*cos(2*pi*x)*cos(2*pi*y)*(1 - z)**2"]},
        material={"E": 1.0, "nu": 0.3}, solver={"strategy": "auto"}, verification={"measures": []})
    chosen = studies.run_study(cfg, comm=MPI.COMM_SELF)
    monkeypatch.setattr(compliance, "QUADRATURE_DEGREE", 16)  # the floor of every choice
    monkeypatch.setattr(element, "ERROR_DEGREES", {1: (16, 16, 0.0)})
    raised = studies.run_study(cfg, comm=MPI.COMM_SELF)
    for one, two in zip(chosen, raised):
        assert one.errors == pytest.approx(two.errors, rel=1e-8), one.n
