"""The user's PETSc options before the first level: names matched as PETSc matches them, values against
PETSc's own type lists, and what PETSc itself rejects found on a small system, one line, exit 2."""
import re
from pathlib import Path

import pytest
import yaml
from mpi4py import MPI
from petsc4py import PETSc

from signorini_cli import config
from signorini_cli.app import cli
from signorini_cli.config import petsc_options
from signorini_cli.solve import preflight
from conftest import BASE, merge


def petsc_names(kind):
    """The type names petsc4py lists for one of its Type classes."""
    return sorted({value for name, value in vars(kind).items() if name.isupper()})


@pytest.mark.fast
@pytest.mark.parametrize("ours, theirs", [
    pytest.param(petsc_options.KSP_TYPES, PETSc.KSP.Type, id="ksp"),
    pytest.param(petsc_options.PC_TYPES, PETSc.PC.Type, id="pc"),
    pytest.param(petsc_options.SOLVER_TYPES, PETSc.Mat.SolverType, id="solver"),
    pytest.param(petsc_options.CHOICE["pc_gamg_type"], PETSc.PC.GAMGType, id="gamg"),
])
def test_type_lists_are_petscs(ours, theirs):
    """The checker's lists are the installed PETSc's: a type PETSc knows is never refused by name."""
    assert sorted(ours) == petsc_names(theirs)


@pytest.mark.fast
@pytest.mark.parametrize("name, canonical", [
    ("SNES_TYPE", "snes_type"), ("-Snes_Rtol", "snes_rtol"), ("signorini_3_ksp_type", "ksp_type"),
    ("signorini_ksp_type", "ksp_type"), ("pc_type", "pc_type")])
def test_names_as_petsc_matches_them(name, canonical):
    assert petsc_options.canonical(name) == canonical


def write(tmp_path, **changes):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(merge(BASE, merge({"output": {"dir": str(tmp_path / "out"), "plots": False}},
                                                     changes))))
    return str(path)


def check_rejected_before_any_level(tmp_path, capsys, options, reason):
    comm = MPI.COMM_WORLD
    folder = comm.bcast(str(tmp_path), root=0)
    path = write(Path(folder), solver={"petsc_options": options}) if comm.rank == 0 else None
    path = comm.bcast(path, root=0)
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    if comm.rank == 0:
        assert re.fullmatch(f"signorini: error: {re.escape(path)}: solver.petsc_options: PETSc rejects these "
                            f"options: {reason}\n", err), err
    assert not (Path(folder) / "out" / "t" / "rates.csv").exists()  # refused before level 0

REJECTED = [
    # the default linear solver of these levels is MUMPS LU (solver.DIRECT_MAX_DOFS_2D), which has no ILU
    pytest.param({"pc_type": "ilu"}, r"MatSolverType mumps does not support factorization type ILU for matrix "
                                     r"type (seq|mpi)aij", id="ilu-with-mumps"),
    pytest.param({"pc_type": "spai"}, "Unable to find requested PC type spai", id="pc-not-built"),
    pytest.param({"snes_linesearch_type": "shell"}, "SNESLineSearchShell needs to have a shell function set "
                                                    "with SNESLineSearchShellSetUserFunc", id="shell-line-search"),
]


@pytest.mark.parametrize("options, reason", REJECTED)
def test_options_petsc_rejects_exit_2_before_any_level(tmp_path, capsys, options, reason):
    check_rejected_before_any_level(tmp_path, capsys, options, reason)


@pytest.mark.mpi
@pytest.mark.parametrize("options, reason", REJECTED)
def test_options_petsc_rejects_exit_2_before_any_level_mpi(tmp_path, capsys, options, reason):
    assert MPI.COMM_WORLD.size == 2
    check_rejected_before_any_level(tmp_path, capsys, options, reason)


def test_accepted_options_leave_no_trace(make_config):
    """The trial solves clear their options: nothing of theirs is left for the study's solvers."""
    cfg = make_config(solver={"petsc_options": {"ksp_type": "gmres", "pc_type": "jacobi"}})
    preflight.check_options(cfg.solver, cfg.dimension)
    assert not [key for key in PETSc.Options().getAll() if key.startswith(preflight.PREFIX)]


def test_petsc_error_in_a_solve_is_bad_input():
    """A PETSc error a real solve meets (here: a KSP without operators) becomes one ConfigError line."""
    ksp = PETSc.KSP().create(MPI.COMM_SELF)
    b = PETSc.Vec().createSeq(2)
    with pytest.raises(config.ConfigError, match=r"^solver.petsc_options: PETSc rejects these options in a test: "):
        with preflight.petsc_errors(" in a test"):
            ksp.solve(b, b.duplicate())
    ksp.destroy()


@pytest.mark.fast
def test_command_line_option_wins_over_the_files_however_spelt(tmp_path):
    """`-SNES_MAX_IT 5` on the command line replaces the file's snes_max_it: 3 (PETSc would read one of them)."""
    path = write(tmp_path, solver={"petsc_options": {"snes_max_it": 3, "ksp_rtol": 1e-8}})
    cfg = config.load(path, options=[("SNES_MAX_IT", "5")])
    assert dict(cfg.solver.petsc_options) == {"ksp_rtol": "1e-08", "snes_max_it": "5"}
