"""--resume: finished levels come back from study.h5 unchanged; a changed config is refused by name."""
import csv
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from mpi4py import MPI

from signorini_cli import config, studies
from signorini_cli.app import cli
from signorini_cli.meshing import meshes
from signorini_cli.record import results, resume
from signorini_cli.studies import refinement
from conftest import BASE, merge


def write_config(folder, **changes):
    path = Path(folder) / "c.yaml"
    output = {"dir": str(Path(folder) / "out"), "plots": False}  # figures cost ~2 s a run
    path.write_text(yaml.safe_dump(merge(BASE, dict(changes, output=output))))
    return str(path)


def rows(folder):
    with open(Path(folder) / "out" / "t" / "rates.csv") as f:
        return [{k: v for k, v in row.items() if not results.is_timing(k)} for row in csv.DictReader(f)]


def test_read_levels_round_trip(make_config):
    # from 0 (strategy plain) N=4 converges in 4 Newton steps, N=16 needs 5: a converged and a failed
    # level come back
    cfg = make_config(mesh={"refinements": [4, 16]}, solver={"max_it": 4, "strategy": "plain"})
    levels = studies.run_study(cfg, on_level=lambda done: results.write(studies.study_of(cfg, done)))
    assert [lv.outcome.converged for lv in levels] == [True, False]
    assert resume.read_levels(cfg) == levels


def test_resume_refuses_changed_config(tmp_path, capsys):
    path = write_config(tmp_path)
    assert cli.main(["run", path, "--quiet"]) == cli.EXIT_OK
    assert cli.main(["run", path, "--resume", "--set", "epsilon.theta=2"]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err == (
        f"signorini: error: {path}: --resume: the config changed since {tmp_path}/out/t/study.h5 was "
        "written (epsilon.theta: 1.0 -> 2.0); use --force to start over\n")


def test_resume_accepts_comment_and_description_changes(tmp_path):
    path = write_config(tmp_path)
    assert cli.main(["run", path]) == cli.EXIT_OK
    Path(path).write_text("# a comment\n" + Path(path).read_text() + "description: now described\n")
    assert cli.main(["run", path, "--resume"]) == cli.EXIT_OK


@pytest.mark.parametrize("measures", [pytest.param(None, id="default"), pytest.param(["diff"], id="diff")])
def test_resume_extends_a_finished_study(tmp_path, capsys, monkeypatch, measures):
    """The finished levels' rows are kept and none is solved again: the new level starts from the stored
    finest u_h (solution.h5) and its row is an uninterrupted run's (the successive difference included)."""
    path = write_config(tmp_path, verification={"measures": measures})  # N = 4, 8, finished
    assert cli.main(["run", path, "--quiet"]) == cli.EXIT_OK
    before = rows(tmp_path)
    with h5py.File(Path(tmp_path) / "out" / "t" / "study.h5") as h5:
        kept = [h5[f"level_{k:02d}"].attrs["time_s"] for k in (0, 1)]
    solved, solve_level, built, build = [], refinement.solve_level, [], meshes.build
    monkeypatch.setattr(refinement, "solve_level", lambda cfg, index, *rest, **kw: solved.append(index) or
                        solve_level(cfg, index, *rest, **kw))
    monkeypatch.setattr(meshes, "build", lambda mesh_cfg, contact, n, *rest: built.append(n) or
                        build(mesh_cfg, contact, n, *rest))
    assert cli.main(["run", path, "--resume", "--quiet", "--set", "mesh.refinements=[4, 8, 16]"]) == cli.EXIT_OK
    assert solved == [2]
    # the stored u_h goes on as its grid values; the successive difference needs it on its mesh (N = 8)
    assert 16 in built and (8 in built) == bool(measures)
    monkeypatch.undo()
    extended = rows(tmp_path)
    with h5py.File(Path(tmp_path) / "out" / "t" / "study.h5") as h5:
        assert [h5[f"level_{k:02d}"].attrs["time_s"] for k in (0, 1)] == kept  # read back, not solved again
    assert extended[:2] == before
    fresh = Path(tmp_path) / "fresh"
    fresh.mkdir()
    assert cli.main(["run", write_config(fresh, mesh={"refinements": [4, 8, 16]}, verification={"measures": measures}),
                     "--quiet"]) == cli.EXIT_OK
    assert extended == rows(fresh)  # the rows of an uninterrupted run (timings aside)
    # a list that does not begin with the old one is another study
    assert cli.main(["run", path, "--resume", "--set", "mesh.refinements=[8, 16, 32]"]) == cli.EXIT_BAD_INPUT
    assert "mesh.refinements" in capsys.readouterr().err


def test_resume_without_results_starts_at_level_0(tmp_path):
    assert cli.main(["run", write_config(tmp_path), "--resume"]) == cli.EXIT_OK
    assert [row["level"] for row in rows(tmp_path)] == ["0", "1"]


def test_resume_refuses_results_without_hash(tmp_path, capsys):
    path = write_config(tmp_path)
    assert cli.main(["run", path]) == cli.EXIT_OK
    with h5py.File(tmp_path / "out" / "t" / "study.h5", "r+") as h5:
        del h5.attrs["config_hash"]
    assert cli.main(["run", path, "--resume"]) == cli.EXIT_BAD_INPUT
    assert "study.h5 has no config hash (written before --resume existed); use --force" in capsys.readouterr().err


def test_resume_refuses_csv_without_h5(tmp_path, capsys):
    path = write_config(tmp_path)
    assert cli.main(["run", path]) == cli.EXIT_OK
    (tmp_path / "out" / "t" / "study.h5").unlink()
    assert cli.main(["run", path, "--resume"]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err.endswith("out/t has rates.csv but no study.h5 to resume from; use --force "
                                            "to start over\n")


def test_resume_refuses_unreadable_h5(tmp_path, capsys):
    path = write_config(tmp_path)
    assert cli.main(["run", path]) == cli.EXIT_OK
    (tmp_path / "out" / "t" / "study.h5").write_text("not HDF5")
    capsys.readouterr()
    assert cli.main(["run", path, "--resume"]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert "--resume: " in err and "study.h5: damaged, not readable as HDF5" in err and err.count("\n") == 1


def test_differences_names_changed_keys():
    before = {"alpha": 2.0, "epsilon": {"theta": 1.0, "law": "theta_h"}, "mesh": {"refinements": [4, 8]}}
    now = {"alpha": 2.0, "epsilon": {"theta": 1.0, "law": "constant"}, "mesh": {"refinements": [4, 8, 16]}}
    assert resume.differences(before, now) == ("epsilon.law: 'theta_h' -> 'constant', "
                                               "mesh.refinements: [4, 8] -> [4, 8, 16]")


def test_fingerprint_ignores_output_and_text(make_config):
    cfg = make_config()
    assert config.fingerprint(cfg) == config.fingerprint(make_config(output={"dir": "elsewhere"}, description="x"))
    assert config.fingerprint(cfg) != config.fingerprint(make_config(alpha=2.5))


class Stop(Exception):
    pass


@pytest.mark.mpi
def test_resume_two_ranks(tmp_path):
    """Two ranks stop after level 1 (results and its u_h written), then `--resume` on two ranks finishes the
    study from the stored u_h with the table of an uninterrupted 2-rank run."""
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    folder = Path(comm.bcast(str(tmp_path) if comm.rank == 0 else None))
    paths = {}
    for name in ("cut", "whole"):
        if comm.rank == 0:
            (folder / name).mkdir()
            write_config(folder / name, mesh={"refinements": [4, 8, 12]})
        comm.barrier()
        paths[name] = str(folder / name / "c.yaml")
    cfg = config.load(paths["cut"])

    def stop_after_two(levels):  # as the run's own recording does: the table, then the level's u_h
        results.write(studies.study_of(cfg, levels), status=f"interrupted at level {len(levels)}")
        resume.keep_solution(cfg, levels, comm)
        if len(levels) == 2:
            raise Stop
    with pytest.raises(Stop):
        studies.run_study(cfg, on_level=stop_after_two)
    assert cli.main(["run", paths["cut"], "--resume"]) == cli.EXIT_OK
    assert cli.main(["run", paths["whole"]]) == cli.EXIT_OK
    same = same_table(rows(folder / "cut"), rows(folder / "whole")) if comm.rank == 0 else None
    assert comm.bcast(same)


def same_table(a, b):
    """Equal tables up to round-off. Two 2-rank runs differ in the last bits (MUMPS's parallel sums):
    seen 2e-16 relative in L2, H1 and the rates, 1e-4 relative in a final residual of 1.5e-12 (noise
    below atol = 1e-12, compared absolutely)."""
    def close(column, x, y):
        if column == "final_residual":
            return float(x) == pytest.approx(float(y), abs=1e-11)
        try:
            return float(x) == pytest.approx(float(y), rel=1e-12)
        except ValueError:
            return x == y  # true/false, reasons, empty cells
    return len(a) == len(b) and all(row_a.keys() == row_b.keys() and
                                    all(close(k, row_a[k], row_b[k]) for k in row_a) for row_a, row_b in zip(a, b))


def test_resume_refuses_other_study_types(tmp_path, capsys):
    path = write_config(tmp_path, study_type="signorini", alpha=None, epsilon=None,
                        problem={"exact": None, "f": "-10"})
    assert cli.main(["run", path, "--resume"]) == cli.EXIT_BAD_INPUT
    assert capsys.readouterr().err == (f"signorini: error: {path}: --resume: study_type signorini runs from the "
                                       "start; use --force to start over\n")


def stopped_study(tmp_path, refinements=(4, 8, 12)):
    """A study run to its end, then cut back to its first two levels as a killed run leaves it."""
    path = write_config(tmp_path, mesh={"refinements": list(refinements)})
    assert cli.main(["run", path, "--quiet"]) == cli.EXIT_OK
    folder = Path(tmp_path) / "out" / "t"
    return path, folder


def refused_once(path, capsys, *expected):
    """--resume ends with exit 2 and one line naming the damage; nothing solved, nothing rewritten."""
    folder = Path(path).parent / "out" / "t"
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert cli.main(["run", path, "--resume", "--quiet"]) == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"signorini: error: {path}: --resume: ") and "Traceback" not in err
    for text in expected:
        assert text in err
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before  # rates.csv keeps every row


def test_resume_refuses_a_missing_level_group(tmp_path, capsys):
    """A level group gone from the middle: refused by its index (never solved again, no row dropped)."""
    path, folder = stopped_study(tmp_path)
    with h5py.File(folder / "study.h5", "a") as h5:
        del h5["level_01"]
    refused_once(path, capsys, "no group level_01", "use --force to start over")


@pytest.mark.parametrize("name, value, wanted", [
    ("N", "eight", "not a whole number"), ("converged", 2.5, "not true or false"),
    ("h", float("nan"), "not a finite number"), ("newton_its", 3.5, "not a whole number")])
def test_resume_refuses_a_wrong_typed_attribute(tmp_path, capsys, name, value, wanted):
    path, folder = stopped_study(tmp_path, (4, 8))
    with h5py.File(folder / "study.h5", "a") as h5:
        h5["level_01"].attrs[name] = value
    refused_once(path, capsys, f"level_01 attribute {name} is", wanted)


def test_resume_refuses_a_level_without_history(tmp_path, capsys):
    path, folder = stopped_study(tmp_path, (4, 8))
    with h5py.File(folder / "study.h5", "a") as h5:
        del h5["level_00/residuals"]
    refused_once(path, capsys, "level_00 is damaged")


def test_resume_reads_levels_by_index_and_keeps_every_row(tmp_path):
    """Levels come back in index order whatever order HDF5 lists them in; a resumed study's rates.csv
    has every row the stopped one had, unchanged, and the rest."""
    path, folder = stopped_study(tmp_path, (4, 8))
    complete = rows(tmp_path)
    cfg = config.load(path)
    levels = resume.read_levels(cfg)
    assert [lv.index for lv in levels] == [0, 1] and [lv.n for lv in levels] == [4, 8]
    results.write(studies.study_of(cfg, levels[:1]))  # as a run stopped after level 0 leaves it
    assert cli.main(["run", path, "--resume", "--quiet"]) == cli.EXIT_OK
    assert same_table(rows(tmp_path), complete)


def test_resume_refuses_a_record_without_its_table(tmp_path, capsys):
    path, folder = stopped_study(tmp_path, (4, 8))
    with h5py.File(folder / "study.h5", "a") as h5:
        del h5["table"]
    refused_once(path, capsys, "no table group")


@pytest.mark.fast
def test_stored_points_matched_bit_for_bit():
    """Each dof point finds the stored point it equals (any order, a rank's subset); a point stored
    nowhere (another mesh) gives None, and the finished levels are then solved again."""
    points = np.random.default_rng(3).random((50, 3))
    subset = np.random.default_rng(4).permutation(50)[:20]
    assert np.array_equal(refinement.matching_points(points, points[subset]), subset)
    moved = points[subset].copy()
    moved[5, 1] += 1e-15
    assert refinement.matching_points(points, moved) is None
    assert refinement.matching_points(points, np.zeros((0, 3))).size == 0
