"""Data-only elastic studies (f = 0, driven by the gap, no exact solution) are measured as the scalar data-only
scenes are: against each level's problem solved on its mesh refined once, and by successive differences."""
import numpy as np
import yaml
from mpi4py import MPI

from signorini_cli import config, studies

SCENE = {"study": "t", "mesh": {"kind": "unit_square", "refinements": [8, 16, 32]}, "contact": "bottom",
         "alpha": 1.0, "epsilon": {"law": "constant", "theta": 1e-3},
         "problem": {"pde": "elasticity", "gap": "(x - 0.5)**2/2 - 0.01"}, "material": {"E": 1.0, "nu": 0.3},
         "verification": {"reference_refinements": 1}}


def test_elastic_data_only_against_references(tmp_path):
    """N = 8, 16, 32 at ε = 1e-3: L2_ref falls at rates 1.35 then 2.05 and H1_ref at 0.49 then 0.85 (measured,
    pre-asymptotic on the coarsest pair: the contact zone a ≈ 0.14 spans one or two cells at N = 8); the finest
    rates' margins 0.3 and 0.2 are that drift. The successive differences fall too."""
    cfg = config.loads(yaml.safe_dump(dict(SCENE, output={"dir": str(tmp_path)})))
    assert cfg.verification.measures == ("penetration", "contact_measure", "contact_force", "diff")
    levels = studies.run_study(cfg, comm=MPI.COMM_SELF)
    rows = studies.of(cfg.study_type).tables(cfg, levels)["rates"]
    assert all(r["converged"] for r in rows)
    for norm, low in (("L2_ref", 2.0 - 0.3), ("H1_ref", 1.0 - 0.2)):
        assert rows[-1][f"rate_{norm}"] >= low, (norm, [r[norm] for r in rows])
    diff = [r["diff_L2"] for r in rows[1:]]
    assert np.all(np.diff(diff) < 0)
