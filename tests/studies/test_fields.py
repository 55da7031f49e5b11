"""output.fields: u_h, its nodal error and the Γ_C contact indicator per level as XDMF (one grid: ParaView
and meshio), serial and 2 ranks."""
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from mpi4py import MPI

from signorini_cli import studies


def check_fields(cfg, levels):
    """Read the XDMF's HDF5 back: error = u_h − u_ex at the nodes, contact = 1 exactly where u_h > 0 on y = 0."""
    for lv in levels:
        with h5py.File(cfg.output_dir / "fields" / f"level_{lv.index:02d}.h5", "r") as h5:
            x = h5["Mesh/mesh/geometry"][:]
            u_h, error, contact = (h5[f"Function/{name}/0"][:, 0] for name in ("u_h", "error", "contact"))
            tags = h5["MeshTags/boundary/Values"][:]
        u_exact = np.sin(2 * np.pi * x[:, 0]) * (1 - x[:, 1]) ** 2
        assert len(u_h) == lv.dofs and set(np.unique(tags)) == {1, 2}
        assert np.allclose(error, u_h - u_exact, atol=1e-14)  # interpolation is exact at the nodes
        assert np.array_equal(contact == 1, (x[:, 1] == 0) & (u_h > 0))
        assert 0 < contact.sum() < np.sum(x[:, 1] == 0)  # part of Γ_C is in contact, part is not


def test_fields_written_per_level(make_config):
    cfg = make_config(output={"fields": True})
    check_fields(cfg, studies.run_study(cfg))


def test_fields_one_grid_for_paraview_and_meshio(make_config):
    cfg = make_config(mesh={"refinements": [4]}, output={"fields": True})
    (level,) = studies.run_study(cfg)
    path = cfg.output_dir / "fields" / "level_00.xdmf"
    grids = ET.parse(path).getroot().findall("Domain/Grid")  # meshio: "Only supports one grid"
    assert len(grids) == 1 and [a.get("Name") for a in grids[0].findall("Attribute")] == ["u_h", "error", "contact"]
    boundary = ET.parse(path.with_name("level_00_boundary.xdmf")).getroot().findall("Domain/Grid")
    assert [g.get("Name") for g in boundary] == ["boundary"] and boundary[0].find("Geometry") is not None
    meshio = pytest.importorskip("meshio")  # python3-meshio
    mesh = meshio.read(path)
    assert len(mesh.points) == level.dofs and set(mesh.point_data) == {"u_h", "error", "contact"}
    with h5py.File(path.with_suffix(".h5"), "r") as h5:
        assert np.array_equal(mesh.point_data["u_h"][:, 0], h5["Function/u_h/0"][:, 0])


def test_fields_off_by_default(make_config):
    cfg = make_config(mesh={"refinements": [4]})
    studies.run_study(cfg)
    assert not (cfg.output_dir / "fields").exists()


@pytest.mark.mpi
def test_fields_two_ranks(make_config, tmp_path_factory):
    comm = MPI.COMM_WORLD
    assert comm.size == 2
    folder = comm.bcast(str(tmp_path_factory.mktemp("fields")) if comm.rank == 0 else None)
    cfg = make_config(output={"fields": True, "dir": folder})
    levels = studies.run_study(cfg)
    failures = []
    if comm.rank == 0:
        try:
            check_fields(cfg, levels)
        except AssertionError as err:
            failures.append(str(err))
    assert not comm.allreduce(failures)  # both ranks fail together, neither hangs
