"""The memory check: a finest level too big for the machine is refused up front, unless --force."""
import re
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml
from mpi4py import MPI

from signorini_cli import cli, resources
from conftest import BASE, merge


@pytest.mark.parametrize("mesh, n, expected", [
    pytest.param(SimpleNamespace(kind="unit_square", diagonal="right"), 8, (81, 7 * 81), id="square"),
    pytest.param(SimpleNamespace(kind="unit_square", diagonal="crossed"), 8, (81 + 64, 9 * 81 + 5 * 64),
                 id="crossed"),
    pytest.param(SimpleNamespace(kind="unit_cube", diagonal="right"), 4, (125, 15 * 125), id="cube"),
    pytest.param(SimpleNamespace(kind="gmsh_file", diagonal="right"), 4, None, id="unknown-kind"),
])
def test_level_size(mesh, n, expected):
    assert resources.level_size(mesh, n) == expected


@pytest.mark.parametrize("diagonal", ["right", "crossed"])
def test_level_size_matches_the_mesh(make_config, diagonal):
    """The dofs formula against dolfinx (the nonzero counts are upper bounds: boundary rows have fewer)."""
    from signorini_cli import study
    cfg = make_config(mesh={"refinements": [6], "diagonal": diagonal})
    (level,) = study.run_study(cfg, comm=MPI.COMM_SELF)
    assert resources.level_size(cfg.mesh, 6)[0] == level.dofs


def write(tmp_path, **changes):
    path = tmp_path / "c.yaml"
    output = {"dir": str(tmp_path / "out"), "plots": False}  # figures cost ~2 s a run
    path.write_text(yaml.safe_dump(merge(BASE, dict(changes, output=output))))
    return str(path)


def test_too_big_refused_with_estimate(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(resources, "available_bytes", lambda: 2**30)
    path = write(tmp_path, mesh={"refinements": [8, 1024]})
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    # 1025^2 = 1,050,625 dofs, 7 nonzeros per row: 100 MiB + 1000 B/dof + 110 B/nonzero = 1.83 GiB
    assert capsys.readouterr().err == (
        f"signorini: error: {path}: mesh.refinements: the finest level (N=1024: 1,050,625 dofs, 7,354,375 "
        "Jacobian nonzeros) needs about 1.8 GiB of memory, more than the 1.0 GiB available; use --force to "
        "run it anyway\n")
    assert not (tmp_path / "out").exists()  # refused before anything was built or written


def test_data_only_counts_its_reference_solution(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(resources, "available_bytes", lambda: 2**30)
    path = write(tmp_path, mesh={"refinements": [8, 512]}, problem={"exact": None, "f": "-10"})
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    # 513^2 + 1025^2 = 1,313,794 dofs (the reference mesh is twice finer), 7 nonzeros per row: 2.3 GiB
    assert capsys.readouterr().err == (
        f"signorini: error: {path}: mesh.refinements: the finest level with its reference solution (N=512 and "
        "N=1024: 1,313,794 dofs, 9,196,558 Jacobian nonzeros) needs about 2.3 GiB of memory, more than the 1.0 "
        "GiB available; use --force to run it anyway\n")


def test_force_runs_anyway(tmp_path, monkeypatch):
    monkeypatch.setattr(resources, "available_bytes", lambda: 1)
    assert cli.main(["run", write(tmp_path)]) == cli.EXIT_BAD_INPUT
    assert cli.main(["run", write(tmp_path), "--force"]) == cli.EXIT_OK


def test_huge_cube_refused_on_this_machine(tmp_path, capsys):
    path = write(tmp_path, dimension=3, mesh={"kind": "unit_cube", "refinements": [4, 2000]},
                 problem={"exact": "x*y*z"})
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    assert re.fullmatch(r"signorini: error: .*: mesh\.refinements: the finest level \(N=2000: 8,012,006,001 dofs, "
                        r"120,180,090,015 Jacobian nonzeros\) needs about 19773\.8 GiB of memory, more than the "
                        r"[\d.]+ GiB available; use --force to run it anyway\n", capsys.readouterr().err)


def test_available_bytes_plausible():
    total = int(Path("/proc/meminfo").read_text().split()[1]) * 1024  # MemTotal, the first line
    assert 0 < resources.available_bytes() <= total


@pytest.mark.mpi
def test_available_on_nodes_same_on_all_ranks():
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    have = resources.available_on_nodes(comm)
    assert len(set(comm.allgather(have))) == 1 and have > 0
