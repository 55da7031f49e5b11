"""Shared fixtures: a config factory for small studies; the solved Problem of a level; a contact term's
assembly beside UFL's."""
import copy
import os
import subprocess
from contextlib import contextmanager

import numpy as np
import pytest
import yaml

from mpi4py import MPI

from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc

from signorini_cli import config
from signorini_cli.solve import strategies
from signorini_cli.studies import refinement as refinement_study

BASE = {
    "study": "t",
    "dimension": 2,
    "alpha": 2.0,
    "epsilon": {"law": "theta_h", "theta": 1.0},
    "mesh": {"kind": "unit_square", "refinements": [4, 8]},
    "contact": "bottom",
    "problem": {"exact": "sin(2*pi*x)*(1-y)**2"},
}


def merge(base, changes):
    """A deep copy of `base` with nested `changes` applied (None deletes a key)."""
    out = copy.deepcopy(base)
    for key, value in changes.items():
        if value is None:
            out.pop(key, None)
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


@pytest.fixture
def raw_config():
    """The raw mapping of a small valid 2-D study, to be varied per test."""
    return copy.deepcopy(BASE)


@pytest.fixture
def make_config(tmp_path):
    """make_config(**changes) -> a validated Config writing under tmp_path."""
    def make(**changes):
        raw = merge(BASE, {"output": {"dir": str(tmp_path / "results")}})
        return config.loads(yaml.safe_dump(merge(raw, changes)))
    return make

# The manufactured Signorini solution of docs/signorini-solution.md (contact x < 1/2, free x > 1/2 on y = 0)
U_SIGNORINI = "y*(abs(x-0.5)-x+0.5)**3 - (abs(x-0.5)+x-0.5)**3*(1-y**2)"


class Interrupt(Exception):
    """Raised after a level to stop a study the way a kill would."""


@pytest.fixture
def partial_study(make_config):
    """A 3-level study stopped after its second level: what a killed run leaves on disk."""
    from signorini_cli import studies
    from signorini_cli.record import results
    cfg = make_config(mesh={"refinements": [4, 8, 16]})

    def write_then_stop(levels):
        results.write(studies.study_of(cfg, levels))
        if len(levels) == 2:
            raise Interrupt

    with pytest.raises(Interrupt):
        studies.run_study(cfg, on_level=write_then_stop)
    return cfg


@contextmanager
def mounted(folder, options):
    """A tmpfs mounted on `folder` (root only: the test is skipped elsewhere), unmounted after."""
    folder.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
                                           capture_output=True).returncode != 0:
        pytest.skip("needs root to mount a tmpfs")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def solved_problem(cfg, monkeypatch, comm=MPI.COMM_SELF):
    """The Problem of cfg's first level, solved (caught on its way to strategies.solve)."""
    seen, original = [], strategies.solve

    def spy(solver_cfg, problem, previous=None, monitor=None, phases=None):
        seen.append(problem)
        return original(solver_cfg, problem, previous, monitor, phases)

    monkeypatch.setattr(strategies, "solve", spy)
    refinement_study.solve_level(cfg, 0, cfg.mesh.refinements[0], comm)
    return seen[-1]


def assembled_beside_ufl(term, F, J, u_h):
    """(b, b_ufl, A, A_ufl): a contact term's residual and Jacobian (term.add_residual, add_jacobian) beside UFL's
    assembly of the forms F, J."""
    b_ufl = fem_petsc.assemble_vector(fem.form(F))
    b_ufl.ghostUpdate(addv=2, mode=1)  # ADD, REVERSE
    b = fem_petsc.create_vector(fem.form(F))
    with b.localForm() as local:
        local.set(0.0)
        term.add_residual(local.array_w)
    b.ghostUpdate(addv=2, mode=1)
    A_ufl = fem_petsc.assemble_matrix(fem.form(J))
    A_ufl.assemble()
    A = fem_petsc.create_matrix(fem.form(J))
    term.add_jacobian(A, np.zeros(u_h.x.array.size, dtype=bool))
    A.assemble()
    return b, b_ufl, A, A_ufl
