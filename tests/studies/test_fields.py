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


# --- elasticity: u_h, σ(u_h), von Mises and the contact pressure ------------------------------------------

ELASTIC = {"problem": {"pde": "elasticity", "exact": ["0.1*sin(pi*x)*y", "0.1*cos(2*pi*x)*(1 - y)**2"]},
           "material": {"E": 1.0, "nu": 0.3}, "mesh": {"refinements": [4, 8]}, "output": {"fields": True}}
MU, LMBDA = 1 / 2.6, 0.3 / (1.3 * 0.4)  # the Lamé constants of E = 1, ν = 0.3


def stresses(x, cells, u):
    """σ (cells, 3, 3, plane strain) of the P1 field u at the nodes x, from each triangle's own gradient."""
    X, U = x[cells][..., :2], u[cells][..., :2]
    edges = X[:, 1:] - X[:, :1]
    grad = np.einsum("cij,cjk->cki", np.linalg.inv(edges), U[:, 1:] - U[:, :1])  # grad[c, i, j] = ∂u_i/∂x_j
    strain = (grad + grad.transpose(0, 2, 1)) / 2
    trace = np.trace(strain, axis1=1, axis2=2)
    s = np.zeros((len(cells), 3, 3))
    s[:, :2, :2] = 2 * MU * strain + LMBDA * trace[:, None, None] * np.eye(2)
    s[:, 2, 2] = LMBDA * trace
    return s


def check_elastic_fields(cfg, levels):
    """The stored σ, von Mises and pressure equal those recomputed from the stored u_h to round-off; the
    exact fields are u_ex at the nodes and the compliance pressure of u_ex."""
    for lv in levels:
        with h5py.File(cfg.output_dir / "fields" / f"level_{lv.index:02d}.h5", "r") as h5:
            x, cells = h5["Mesh/mesh/geometry"][:], h5["Mesh/mesh/topology"][:]
            read = {name: h5[f"Function/{name}/0"][:] for name in h5["Function"]}
        assert set(read) == {"u_h", "error", "sigma", "von_mises", "pressure", "u_exact", "sigma_exact",
                             "von_mises_exact", "pressure_exact"}
        s = stresses(x, cells, read["u_h"])
        assert np.allclose(read["sigma"].reshape(-1, 3, 3)[:, :2, :2], s[:, :2, :2], atol=1e-12)
        dev = s - np.trace(s, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
        assert np.allclose(read["von_mises"][:, 0], np.sqrt(1.5 * np.sum(dev * dev, axis=(1, 2))), atol=1e-12)
        u_exact = np.stack((0.1 * np.sin(np.pi * x[:, 0]) * x[:, 1],
                            0.1 * np.cos(2 * np.pi * x[:, 0]) * (1 - x[:, 1]) ** 2), 1)
        assert np.allclose(read["u_exact"][:, :2], u_exact, atol=1e-14)
        assert np.allclose(read["error"][:, :2], read["u_h"][:, :2] - u_exact, atol=1e-14)
        bottom = x[:, 1] == 0  # Γ_C, n = (0, −1): w = −u_y, p = [w]_+^2 / ε
        for name, u in (("pressure", read["u_h"]), ("pressure_exact", u_exact)):
            expected = np.where(bottom, np.maximum(-u[:, 1], 0) ** 2 / lv.eps, 0.0)
            assert np.allclose(read[name][:, 0], expected, rtol=1e-12, atol=1e-14)
        assert 0 < np.count_nonzero(read["pressure"]) < np.count_nonzero(bottom)  # part of Γ_C in contact


def test_elastic_fields(make_config):
    cfg = make_config(**ELASTIC)
    check_elastic_fields(cfg, studies.run_study(cfg))
    meshio = pytest.importorskip("meshio")  # ParaView's XDMF reader takes what meshio takes: one grid
    mesh = meshio.read(cfg.output_dir / "fields" / "level_01.xdmf")
    assert set(mesh.point_data) == {"u_h", "error", "pressure", "u_exact", "pressure_exact"}
    assert set(mesh.cell_data) == {"sigma", "von_mises", "sigma_exact", "von_mises_exact"}


@pytest.mark.mpi
def test_elastic_fields_two_ranks(make_config, tmp_path_factory):
    comm = MPI.COMM_WORLD
    folder = comm.bcast(str(tmp_path_factory.mktemp("elastic_fields")) if comm.rank == 0 else None)
    cfg = make_config(**dict(ELASTIC, output={"fields": True, "dir": folder}))
    levels = studies.run_study(cfg)
    failures = []
    if comm.rank == 0:
        try:
            check_elastic_fields(cfg, levels)
        except AssertionError as err:
            failures.append(str(err))
    assert not comm.allreduce(failures)
