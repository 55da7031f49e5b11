"""The memory check: a finest level too big for the machine is refused up front, unless --ignore-memory-check."""
import dataclasses
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from mpi4py import MPI

from signorini_cli import config
from signorini_cli.app import cli, resources
from signorini_cli.config import geometry_files
from signorini_cli.meshing import geometries
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
    from signorini_cli import studies
    cfg = make_config(mesh={"refinements": [6], "diagonal": diagonal})
    (level,) = studies.run_study(cfg, comm=MPI.COMM_SELF)
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
        "Jacobian nonzeros) needs about 1.8 GiB of memory, more than the 1.0 GiB available; use "
        "--ignore-memory-check to run it anyway\n")
    assert not (tmp_path / "out").exists()  # refused before anything was built or written


def test_data_only_counts_its_reference_solution(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(resources, "available_bytes", lambda: 2**30)
    path = write(tmp_path, mesh={"refinements": [8, 512]}, problem={"exact": None, "f": "-10"})
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    # 513^2 + 2049^2 = 4,461,570 dofs (the reference mesh is two refinements finer, the default depth), 7
    # nonzeros per row: 100 MiB + 1000 B/dof + 110 B/nonzero = 7.5 GiB
    assert capsys.readouterr().err == (
        f"signorini: error: {path}: mesh.refinements: the finest level with its reference solution (N=512 and "
        "N=2048: 4,461,570 dofs, 31,230,990 Jacobian nonzeros) needs about 7.5 GiB of memory, more than the 1.0 "
        "GiB available; use --ignore-memory-check to run it anyway\n")


def test_ignore_memory_check_runs_anyway(tmp_path, monkeypatch):
    monkeypatch.setattr(resources, "available_bytes", lambda: 1)
    assert cli.main(["run", write(tmp_path)]) == cli.EXIT_BAD_INPUT
    assert cli.main(["run", write(tmp_path), "--ignore-memory-check"]) == cli.EXIT_OK


def test_force_keeps_the_memory_check(tmp_path, monkeypatch):
    """--force starts over; it no longer switches the memory check off (a forced 3-D N = 400 run was killed
    by the kernel's out-of-memory killer)."""
    monkeypatch.setattr(resources, "available_bytes", lambda: 1)
    assert cli.main(["run", write(tmp_path), "--force"]) == cli.EXIT_BAD_INPUT


def test_huge_cube_refused_on_this_machine(tmp_path, capsys):
    path = write(tmp_path, dimension=3, mesh={"kind": "unit_cube", "refinements": [4, 2000]},
                 problem={"exact": "x*y*z"})
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    assert re.fullmatch(r"signorini: error: .*: mesh\.refinements: the finest level \(N=2000: 8,012,006,001 dofs, "
                        r"120,180,090,015 Jacobian nonzeros\) needs about 19773\.8 GiB of memory, more than the "
                        r"[\d.]+ GiB available; use --ignore-memory-check to run it anyway\n", capsys.readouterr().err)


def test_available_bytes_plausible():
    total = int(Path("/proc/meminfo").read_text().split()[1]) * 1024  # MemTotal, the first line
    assert 0 < resources.available_bytes() <= total


@pytest.mark.mpi
def test_available_on_nodes_same_on_all_ranks():
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    have = resources.available_on_nodes(comm)
    assert len(set(comm.allgather(have))) == 1 and have > 0


# --- gmsh and file meshes: estimated before meshing -------------------------------------------------

def gmsh_config(tmp_path, **mesh):
    mesh = dict({"kind": "gmsh", "geometry": "unit_square", "cache": str(tmp_path / "cache"), "refinements": None},
                **mesh)
    dimension = 3 if mesh["geometry"] in ("unit_cube", "half_ball") else 2
    exact = "x*y*z" if dimension == 3 else "x*y"
    return write(tmp_path, mesh=mesh, contact="contact", dimension=dimension, problem={"exact": exact})


def test_gmsh_size_too_small_refused_before_meshing(tmp_path, capsys, monkeypatch):
    def no_meshing(*args):
        raise AssertionError("gmsh meshed a level")
    monkeypatch.setattr(geometries, "generate", no_meshing)
    path = gmsh_config(tmp_path, sizes=[0.2, 1e-4])
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    # |Ω| = 1 at size 1e-4: 1.15e8 vertices (2/sqrt(3) per size^2), 7 nonzeros per row, (1000 + 7 * 110) B
    # per dof: 203.6 GB = 189.6 GiB, + 100 MiB per rank
    assert re.fullmatch(r"signorini: error: .*: mesh\.sizes: the finest level \(size 0\.0001: 115,000,000 dofs, "
                        r"805,000,000 Jacobian nonzeros\) needs about 189\.7 GiB of memory, more than the "
                        r"[\d.]+ GiB available; use --ignore-memory-check to run it anyway\n", capsys.readouterr().err)
    assert not (tmp_path / "cache").exists() and not (tmp_path / "out").exists()  # nothing left behind


def test_msh_file_refined_too_often_refused(tmp_path, capsys):
    msh = Path(__file__).resolve().parents[2] / "meshes/examples/quarter_annulus.msh"
    path = write(tmp_path, mesh={"kind": "file", "path": str(msh), "refine": "uniform", "refinements": [0, 12]},
                 contact="inner_arc", problem={"exact": "cos(pi*x)*sin(pi*y)"})
    assert cli.main(["run", path]) == cli.EXIT_BAD_INPUT
    # 68 nodes in the file's header, 4^12 times more after 12 uniform refinements: 1,140,850,688 dofs
    assert re.fullmatch(r"signorini: error: .*: mesh\.refinements: the finest level \(quarter_annulus\.msh refined "
                        r"12 times: 1,140,850,688 dofs, 7,985,954,816 Jacobian nonzeros\) needs about .* GiB of "
                        r"memory, more than the [\d.]+ GiB available; use --ignore-memory-check to run it anyway\n",
                        capsys.readouterr().err)


def test_gmsh_data_only_counts_its_reference(tmp_path, monkeypatch):
    cfg = config.load(gmsh_config(tmp_path, sizes=[0.1, 0.01]))
    cfg = dataclasses.replace(cfg, problem=dataclasses.replace(cfg.problem, exact=None))
    peak = resources.peak_meshes(cfg, MPI.COMM_SELF)
    # 1.15 / 0.01^2 = 11,500 vertices, and 16 times as many after the reference's two refinements (the default)
    assert [(label, dofs) for label, dofs, _ in peak] == [("size 0.01", 11500), ("size 0.01 refined 2 times", 184000)]


@pytest.mark.parametrize("geometry, size", [("unit_square", 0.02), ("half_disk", 0.02), ("l_shape", 0.05),
                                            ("unit_cube", 0.1), ("half_ball", 0.1)])
def test_gmsh_estimate_close_to_the_mesh(tmp_path, geometry, size):
    """The estimate against the nodes gmsh makes (an independent count, from the mesh file gmsh writes):
    within 30 % (the boundary's extra vertices at these coarse sizes; they shrink with the size)."""
    cfg = config.load(gmsh_config(tmp_path, geometry=geometry, sizes=[size]))
    ((_, estimate, _),) = resources.peak_meshes(cfg, MPI.COMM_SELF)
    path, _ = geometries.mesh_file(geometry_files.geometry_path(geometry), size, cfg.mesh.dimension, cfg.mesh.cache)
    gmsh = geometries._import_gmsh()
    gmsh.initialize()
    try:
        gmsh.open(str(path))
        meshed = len(gmsh.model.mesh.getNodes()[0])
    finally:
        geometries._finalize(gmsh)
    assert 0.7 * meshed <= estimate <= meshed
    ((_, cached, _),) = resources.peak_meshes(cfg, MPI.COMM_SELF)
    assert cached == meshed  # once in the cache, its header's exact count


@pytest.mark.parametrize("version, binary", [(4.1, 0), (4.1, 1), (2.2, 0), (2.2, 1)])
def test_msh_node_count_reads_the_header(tmp_path, version, binary):
    gmsh = geometries._import_gmsh()
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(geometry_files.geometry_path("half_disk")))
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.1)
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.option.setNumber("Mesh.Binary", binary)
        gmsh.write(str(tmp_path / "m.msh"))
        gmsh.clear()
        gmsh.open(str(tmp_path / "m.msh"))  # the nodes the file holds (not the unused arc centre)
        nodes = len(gmsh.model.mesh.getNodes()[0])
    finally:
        geometries._finalize(gmsh)
    assert geometry_files.msh_node_count(tmp_path / "m.msh") == nodes
    assert geometry_files.msh_node_count(tmp_path / "m.msh", chunk=7) == nodes  # a header cut between chunks


@pytest.mark.parametrize("geometry, dim, measure, rel", [
    ("unit_square", 2, 1.0, 1e-12), ("l_shape", 2, 3.0, 1e-12), ("unit_cube", 3, 1.0, 1e-12),
    # curved: the inscribed polygon of cells a tenth of the diameter misses a few % of the disk/ball
    ("half_disk", 2, np.pi / 2, 0.02), ("half_ball", 3, 2 * np.pi / 3, 0.05)])
def test_geometry_measure(geometry, dim, measure, rel):
    assert geometries.geometry_measure(geometry_files.geometry_path(geometry), dim) == pytest.approx(measure, rel=rel)
