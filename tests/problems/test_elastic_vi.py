"""The elastic Signorini problem (bounds on u·n = ±u_k on a face of the unit square): its contact force equals
the penalty's at ε = 1e-10, and the ε-sweep's model error ||u_ε,h − u_S,h|| falls to 0 as ε → 0."""
import numpy as np
import pytest
import yaml
from mpi4py import MPI

from signorini_cli import config, studies

# a rigid parabola (radius 1) 0.01 into the bottom face: contact around x = 1/2, f = 0, u = 0 on the other faces
SCENE = {"study": "t", "mesh": {"kind": "unit_square", "refinements": [16, 32]}, "contact": "bottom",
         "problem": {"pde": "elasticity", "gap": "(x - 0.5)**2/2 - 0.01"}, "material": {"E": 1.0, "nu": 0.3}}


def load(tmp_path, **changes):
    return config.loads(yaml.safe_dump(dict(SCENE, output={"dir": str(tmp_path)}, **changes)))


def test_vi_force_equals_penalty_at_tiny_eps(tmp_path):
    """N = 16, 32: the VI's force Σλ_i and the penalty's (1/ε)∫[u_h·n − g0]_+ at ε = 1e-10 (α = 1) agree to
    6.6e-9 and 5.7e-8 (measured); the bound 1e-6. At N = 8 one node touches and they differ by 1.8e-6: there
    the penalty's contact set is a sliver of width ~ε around the node, so it nears the VI more slowly."""
    vi = studies.run_study(load(tmp_path / "vi", study_type="signorini"), comm=MPI.COMM_SELF)
    penalty = studies.run_study(load(tmp_path / "pen", alpha=1.0, epsilon={"law": "constant", "theta": 1e-10}),
                                comm=MPI.COMM_SELF)
    for a, b in zip(vi, penalty):
        assert a.outcome.converged and b.outcome.converged
        assert a.extra["contact_nodes"] >= 3
        assert abs(a.extra["contact_force"] / b.extra["contact_force"] - 1) <= 1e-6


def test_model_error_falls_with_eps(tmp_path):
    """N = 16: the L2, H1 and L2(Γ_C) model errors fall monotonically, at the fitted slope 1/α over the three
    smallest ε (measured 1.00 for α = 1, 0.49 for α = 2)."""
    cfg = load(tmp_path, study_type="epsilon_sweep", mesh={"kind": "unit_square", "refinements": [16]},
               limit={"alpha": [1, 2], "epsilon": [1e-2, 1e-4, 1e-6, 1e-8, 1e-10]})
    sweep = studies.run_study(cfg, comm=MPI.COMM_SELF)
    assert all(p.outcome.converged for p in sweep)
    named = studies.of(cfg.study_type).tables(cfg, sweep)
    for alpha in (1, 2):
        rows = [r for r in named["sweep"] if r["alpha"] == alpha]
        for norm in ("L2", "H1", "L2_gamma_c", "penetration"):
            values = [r[norm] for r in rows]
            assert all(b < a for a, b in zip(values, values[1:])), (alpha, norm, values)
        fit = next(r for r in named["fitted"] if r["alpha"] == alpha)
        assert fit["fit_L2"] == pytest.approx(1 / alpha, abs=0.05)
    assert min(r["L2"] for r in named["sweep"] if r["alpha"] == 1) < 1e-10


@pytest.mark.mpi
def test_vi_two_ranks_equal_one(tmp_path_factory):
    """The elastic VI on 2 ranks: the same contact force and contact set as on one (round-off)."""
    comm = MPI.COMM_WORLD
    folder = comm.bcast(str(tmp_path_factory.mktemp("evi")) if comm.rank == 0 else None)
    cfg = load(folder, study_type="signorini", mesh={"kind": "unit_square", "refinements": [16]})
    both = studies.run_study(cfg)[0]
    one = studies.run_study(cfg, comm=MPI.COMM_SELF)[0] if comm.rank == 0 else None
    failures = []
    if comm.rank == 0:
        if not (both.extra["contact_nodes"] == one.extra["contact_nodes"]
                and np.isclose(both.extra["contact_force"], one.extra["contact_force"], rtol=1e-10)):
            failures.append((both.extra, one.extra))
    assert not comm.allreduce(failures)
