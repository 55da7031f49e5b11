"""Bad input and surroundings beyond the config: argparse's errors, --force, output.fields on a full disk, a
garbage .geo, meshes with fewer cells than ranks; one line and the promised exit status, or correct results."""
import csv
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from mpi4py import MPI

from signorini_cli.app import cli, guard
from signorini_cli.studies import refinement as refinement_study
import failing_run
from conftest import BASE, merge, mounted

SIGNORINI = str(Path(sys.executable).with_name("signorini"))
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1"}


def write_config(folder, refinements=(4, 8), **changes):
    path = Path(folder) / "c.yaml"
    raw = merge(BASE, {"mesh": {"refinements": list(refinements)},
                       "output": {"plots": False, "dir": str(Path(folder) / "out")}})
    path.write_text(yaml.safe_dump(merge(raw, changes)))
    return str(path)


def rows(study):
    with open(Path(study) / "rates.csv") as f:
        return list(csv.DictReader(f))




# --- the command line ----------------------------------------------------------------------------

@pytest.mark.fast
@pytest.mark.parametrize("argv, message", [
    pytest.param(["run", "c.yaml", "--bogus"], "unrecognized arguments: --bogus (see `signorini --help`)",
                 id="unknown-flag"),
    pytest.param(["run"], "the following arguments are required: config (see `signorini run --help`)",
                 id="missing-config"),
    pytest.param([], "the following arguments are required: command (see `signorini --help`)", id="no-command"),
    pytest.param(["frobnicate"], "argument command: invalid choice: 'frobnicate' (choose from 'run', 'check', "
                                 "'init', 'list', 'report', 'compare') (see `signorini --help`)", id="no-such-command"),
])
def test_argparse_errors_one_line(capsys, argv, message):
    """Not argparse's usage (2-4 lines): the one line of every bad input, exit 2."""
    with pytest.raises(SystemExit) as done:
        cli.main(argv)
    assert done.value.code == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err == f"signorini: error: command line: {message}\n"


# --- --force: start over ---------------------------------------------------------------------------

def old_study(tmp_path):
    """A study folder holding an earlier run's results, figures and fields, and a file of the user's."""
    study = tmp_path / "out" / "t"
    (study / "fields").mkdir(parents=True)
    for name in ("rates.csv", "study.h5", "rates.md", "rates.tex", "status.txt", "convergence.png",
                 "convergence.pdf", "fields/level_00.xdmf", "fields/level_00.h5", "notes.txt"):
        (study / name).write_text("old\n")
    return study


def test_force_starts_over(tmp_path):
    study = old_study(tmp_path)
    assert cli.main(["run", write_config(tmp_path), "--force", "--quiet"]) == cli.EXIT_OK
    assert sorted(p.name for p in study.iterdir()) == ["notes.txt", "pressure.csv", "rates.csv", "rates.md",
                                                       "rates.tex", "solution.h5", "status.txt", "study.h5",
                                                       "summary.csv", "verdict.tex", "work_precision.csv"]
    assert (study / "notes.txt").read_text() == "old\n"  # not a result of the study's: kept


def test_forced_run_interrupted_at_level_0_leaves_no_old_tables(tmp_path, monkeypatch):
    """A forced run that ends at level 0 (here a crash inside the level) leaves no old rates.md/tex or
    figures beside its empty rates.csv."""
    study = old_study(tmp_path)
    monkeypatch.setattr(refinement_study, "solve_level", failing_run.failing(refinement_study.solve_level, 0, 0))
    with pytest.raises(RuntimeError, match="rank 0 fails at the start of level 0"):
        cli.main(["run", write_config(tmp_path), "--force", "--quiet"])
    assert not [p.name for p in study.glob("*") if p.suffix in (".md", ".tex", ".png", ".pdf")]
    assert rows(study) == [] and (study / "status.txt").read_text().startswith("failed at level 0")


# --- output.fields on a full disk ----------------------------------------------------------------

def test_fields_on_a_full_disk_one_line(tmp_path):
    """A 500 KiB tmpfs: the XDMF/HDF5 fields of level 2 or 3 find it full (73 lines of HDF5 diagnostics and a
    traceback before): one line, exit 2, the status says why."""
    config = write_config(tmp_path, refinements=(8, 16, 32, 64), output={"fields": True})
    with mounted(tmp_path / "small", "size=500k") as small:
        done = subprocess.run([SIGNORINI, "run", config, "--output", str(small), "--quiet"], capture_output=True,
                              text=True, timeout=300)
        assert done.returncode == guard.BAD_SURROUNDINGS, done.stderr
        assert done.stderr.count("\n") == 1 and "HDF5" not in done.stderr, done.stderr
        assert "cannot write the results: No space left on device" in done.stderr
        assert (small / "t" / "status.txt").read_text().strip().endswith("No space left on device")


# --- a garbage .geo --------------------------------------------------------------------------------

def geo_config(tmp_path, geo_text):
    geo = tmp_path / "garbage.geo"
    geo.write_bytes(geo_text)
    return write_config(tmp_path, contact="contact", problem={"exact": "x*y"},
                        mesh={"kind": "gmsh", "geometry": str(geo), "sizes": [0.5], "refinements": None,
                              "cache": str(tmp_path / "cache" / "sub")})


@pytest.mark.parametrize("geo_text, message", [
    pytest.param(bytes(range(256)), "names no physical group of dimension 2 or 3", id="binary"),
    pytest.param(b'Point(1) = {0, 0, 0};\nLine(1) = {1, 7};\nCurve Loop(1) = {1};\nPlane Surface(1) = {1};\n'
                 b'Physical Surface("domain") = {1};\nPhysical Curve("contact") = {1};\n',
                 "Unknown control point 7 in GEO curve 1", id="gmsh-fails"),
])
def test_garbage_geo_one_line_no_cache_folder(tmp_path, capsys, geo_text, message):
    config = geo_config(tmp_path, geo_text)
    assert cli.main(["run", config]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.startswith(f"signorini: error: {config}: mesh.geometry: ") and message in err, err
    assert err.count("\n") == 1 and not (tmp_path / "cache").exists()  # the folders made for it are gone


# --- fewer cells than ranks ------------------------------------------------------------------------

# N = 1: two triangles; on two ranks the partitioner may leave one without a cell (a crash in the cell
# diameters before). The L2 errors of a serial run (measured, with the data's quadrature chosen on the family's
# coarsest mesh): N = 1 0.3162277591546467, N = 2 0.3038173455932624
SERIAL_L2 = {1: 0.3162277591546467, 2: 0.3038173455932624}


def check_tiny_mesh(tmp_path):
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(str(tmp_path), root=0))
    config = write_config(folder, refinements=(1, 2)) if comm.rank == 0 else None
    assert cli.main(["run", comm.bcast(config, root=0), "--quiet"]) == cli.EXIT_OK
    comm.barrier()
    for row in rows(folder / "out" / "t"):
        # the same discrete problem on any partition: round-off apart (1e-12 relative)
        assert float(row["L2"]) == pytest.approx(SERIAL_L2[int(row["N"])], rel=1e-12)


def test_tiny_mesh(tmp_path):
    check_tiny_mesh(tmp_path)


@pytest.mark.mpi
def test_tiny_mesh_mpi(tmp_path):
    assert MPI.COMM_WORLD.size == 2
    check_tiny_mesh(tmp_path)


@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_three_ranks_on_eight_cells(tmp_path):
    """N = 2 (8 cells) and 4 on three ranks: correct results, the serial run's errors."""
    config = write_config(tmp_path, refinements=(2, 4))
    done = subprocess.run(["mpirun", "-q", "-n", "3", SIGNORINI, "run", config, "--quiet"], capture_output=True,
                          text=True, env=dict(os.environ, **MPI_ENV), timeout=300)
    assert done.returncode == cli.EXIT_OK and done.stderr == "", done.stderr
    # the serial run's L2 at N = 4 (measured): 0.08178397774613129
    assert [float(r["L2"]) for r in rows(tmp_path / "out" / "t")] == pytest.approx(
        [SERIAL_L2[2], 0.08178397774613129], rel=1e-12)


def test_refused_forced_run_keeps_the_old_results(tmp_path, capsys):
    """--force with a config refused before any solve (an option PETSc rejects) removes nothing."""
    study = old_study(tmp_path)
    config = write_config(tmp_path, solver={"petsc_options": {"pc_type": "spai"}})  # not in this PETSc
    assert cli.main(["run", config, "--force", "--quiet"]) == cli.EXIT_BAD_INPUT
    assert "Unable to find requested PC type spai" in capsys.readouterr().err
    assert (study / "rates.md").read_text() == "old\n" and (study / "convergence.png").exists()
