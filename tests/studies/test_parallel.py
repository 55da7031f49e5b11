"""Serial and 2-rank runs agree: in-process on 2 ranks (mpi marker) and through `mpirun -n 2 signorini`."""
import csv
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from mpi4py import MPI

from signorini_cli import config, studies
from conftest import BASE, merge

RTOL = 1e-8  # serial and parallel errors agree to 1e-8 relative (solver tolerance 1e-10)
CASES = [
    pytest.param({}, id="2d"),
    pytest.param({"dimension": 3, "mesh": {"kind": "unit_cube", "refinements": [4, 6]},
                  "problem": {"exact": "sin(2*pi*x)*sin(pi*y)*(1-z)**2"}}, id="3d"),
]


@pytest.mark.mpi
@pytest.mark.parametrize("changes", CASES)
def test_two_ranks_match_one(changes):
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    cfg = config.loads(yaml.safe_dump(merge(BASE, changes)))
    parallel = studies.run_study(cfg, comm=comm)
    serial = studies.run_study(cfg, comm=MPI.COMM_SELF)  # every rank solves the whole problem alone
    for p, s in zip(parallel, serial):
        assert p.outcome.converged and s.outcome.converged
        assert p.dofs == s.dofs and p.h == pytest.approx(s.h, rel=1e-14)
        for norm in ("L2", "H1"):
            assert p.errors[norm] == pytest.approx(s.errors[norm], rel=RTOL)


def read(path):
    with open(path) as f:
        return list(csv.DictReader(f))


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_mpirun_cli_matches_serial(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(merge(BASE, {"mesh": {"refinements": [8, 16]}})))
    exe = str(Path(sys.executable).with_name("signorini"))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    serial = subprocess.run([exe, "run", str(cfg), "--output", str(tmp_path / "s")],
                            capture_output=True, text=True, env=env, timeout=300)
    parallel = subprocess.run(["mpirun", "-n", "2", exe, "run", str(cfg), "--output", str(tmp_path / "p")],
                              capture_output=True, text=True, env=env, timeout=300)
    assert serial.returncode == 0 and parallel.returncode == 0, parallel.stderr
    assert parallel.stdout.count("study t") == 1  # one rank prints
    s_rows, p_rows = read(tmp_path / "s/t/rates.csv"), read(tmp_path / "p/t/rates.csv")
    assert len(s_rows) == len(p_rows) == 2
    for s, p in zip(s_rows, p_rows):
        for norm in ("L2", "H1"):
            assert float(p[norm]) == pytest.approx(float(s[norm]), rel=RTOL)
