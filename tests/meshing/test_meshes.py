"""The built-in meshes built in place on every rank (grids.py): the very cells of dolfinx's own
create_unit_square/cube, shared vertices on the cut, h, the tags of Γ_C and Γ_D, and the errors of every
shipped built-in config against the meshes dolfinx builds itself."""
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import ufl
from mpi4py import MPI

import dolfinx.graph
import dolfinx.mesh
from dolfinx import fem

from signorini_cli import config, studies
from signorini_cli.meshing import grids, meshes


ROOT = Path(__file__).resolve().parents[2]
KINDS = [pytest.param("unit_square", d, id=f"square-{d}") for d in ("right", "left", "crossed")]
KINDS.append(pytest.param("unit_cube", "right", id="cube"))
# Errors of one discrete problem solved twice: serially the meshes are bit for bit the same (so are the
# errors); on 2 ranks the partitions differ, which reorders sums: round-off, ~1e-14 on these small levels.
SAME = 1e-12
# An ε-sweep records differences u_ε,h − u_S,h of two solutions of size ~1: their round-off is relative to
# the solutions, not to the difference (5.380320407052e-07 against ...708e-07 on 2 ranks), so SAME absolute.
SAME_DIFFERENCE = 1e-12


def dolfinx_mesh(comm, kind, n, diagonal):
    """The mesh as today's dolfinx builds it (on rank 0, then partitioned), as meshes.build did before."""
    if kind == "unit_square":
        return dolfinx.mesh.create_unit_square(comm, n, n, diagonal=getattr(dolfinx.mesh.DiagonalType, diagonal))
    return dolfinx.mesh.create_unit_cube(comm, n, n, n)


def cell_set(msh, n):
    """Every rank's owned cells as sorted tuples of vertices in units of 1/(2n), over all ranks."""
    tdim = msh.topology.dim
    owned = msh.topology.index_map(tdim).size_local
    x = msh.geometry.x[msh.geometry.dofmap.array.reshape(-1, tdim + 1)[:owned]][:, :, :tdim]
    local = [tuple(sorted(map(tuple, vertices))) for vertices in np.rint(x * 2 * n).astype(int).tolist()]
    return sorted(sum(msh.comm.allgather(local), []))


def dofs_of(msh):
    return fem.FunctionSpace(msh, ("Lagrange", 1)).dofmap.index_map.size_global


@pytest.mark.fast
@pytest.mark.parametrize("kind, diagonal", KINDS)
@pytest.mark.parametrize("n", [1, 3, 8])
def test_same_cells_as_dolfinx_serial(kind, diagonal, n):
    comm = MPI.COMM_SELF
    dim = 2 if kind == "unit_square" else 3
    ours, theirs = grids.create(comm, dim, n, diagonal), dolfinx_mesh(comm, kind, n, diagonal)
    assert np.array_equal(ours.geometry.x, theirs.geometry.x)  # same input, same order: bit for bit
    assert np.array_equal(ours.geometry.dofmap.array, theirs.geometry.dofmap.array)


@pytest.mark.mpi
@pytest.mark.parametrize("kind, diagonal", KINDS)
@pytest.mark.parametrize("n", [1, 3, 8])
def test_same_cells_as_dolfinx_parallel(kind, diagonal, n):
    comm = MPI.COMM_WORLD
    dim = 2 if kind == "unit_square" else 3
    ours = grids.create(comm, dim, n, diagonal)
    assert cell_set(ours, n) == cell_set(dolfinx_mesh(comm, kind, n, diagonal), n)
    # vertices on the cut are shared, not owned twice: (n+1)^d grid points (+ n^2 centres, crossed)
    assert dofs_of(ours) == (n + 1) ** dim + (n**2 if diagonal == "crossed" else 0)


@pytest.mark.mpi
def test_vertices_on_the_cut_are_shared():
    """The failure of a partition without ghost cells: 90 dofs instead of 81 at N = 8 on 2 ranks."""
    msh = grids.create(MPI.COMM_WORLD, 2, 8, "right")
    assert dofs_of(msh) == 81
    assert msh.comm.allreduce(msh.topology.index_map(0).num_ghosts, op=MPI.SUM) > 0
    owned_cells = msh.comm.allgather(msh.topology.index_map(2).size_local)
    assert owned_cells == [64, 64]  # 4 rows of 16 triangles each: the slabs split the 8 rows evenly


@pytest.mark.fast
@pytest.mark.parametrize("count, size", [(8, 2), (7, 3), (2, 4), (1024, 8)])
def test_local_range_blocks_cover_once(count, size):
    blocks = [grids.local_range(rank, count, size) for rank in range(size)]
    assert blocks[0][0] == 0 and blocks[-1][1] == count
    assert all(a[1] == b[0] for a, b in zip(blocks, blocks[1:]))
    assert max(b - a for a, b in blocks) - min(b - a for a, b in blocks) <= 1
    for rank, (start, stop) in enumerate(blocks):
        assert (grids.row_owner(np.arange(start, stop), count, size) == rank).all()


@pytest.mark.fast
@pytest.mark.parametrize("kind, diagonal", KINDS)
@pytest.mark.parametrize("comm", [pytest.param(MPI.COMM_SELF, id="serial"),
                                  pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)])
def test_size_and_tags(kind, diagonal, comm):
    n, dim = 4, 2 if kind == "unit_square" else 3
    domain = meshes.build(config.Mesh(kind, (n,), diagonal), "bottom", n, comm)
    # every cell's longest edge is the diagonal of its grid square/cube, sqrt(d)/n, except crossed, whose
    # triangles (two corners and the centre) have the square's side 1/n as longest edge
    diameter = 1 / n if diagonal == "crossed" else np.sqrt(dim) / n
    assert (domain.h, domain.h_min) == pytest.approx((diameter, diameter), rel=1e-14)
    assert domain.n == n
    msh, tags = domain.mesh, domain.facet_tags
    owned = tags.indices < msh.topology.index_map(dim - 1).size_local
    counts = [msh.comm.allreduce(int(np.count_nonzero(owned & (tags.values == t))), op=MPI.SUM)
              for t in (meshes.CONTACT, meshes.DIRICHLET)]
    per_face = n ** (dim - 1) * (1 if dim == 2 else 2)  # boundary facets per side: n edges, 2n^2 triangles
    assert counts == [per_face, (2 * dim - 1) * per_face]
    one = fem.Constant(msh, 1.0)
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags)
    measure = [msh.comm.allreduce(fem.assemble_scalar(fem.form(one * ds(t))), op=MPI.SUM)
               for t in (meshes.CONTACT, meshes.DIRICHLET)]
    assert measure == pytest.approx([1.0, 2 * dim - 1], rel=1e-14)  # |Γ_C| = one side, |Γ_D| the others


# --- errors of every shipped built-in config, against dolfinx's own meshes ---------------------------

def shipped_built_in_configs():
    paths = sorted(ROOT.glob("configs/**/*.yaml")) + sorted(ROOT.glob("bench/configs/*.yaml"))
    # a map's points are studies on these same meshes: its first point stands for it
    built_in = [p for p in paths if config.load(p).mesh.kind in ("unit_square", "unit_cube")]
    return [pytest.param(p, id=str(p.relative_to(ROOT))) for p in built_in]


def small(cfg):
    """The config cut to its two coarsest levels (the first one halved for the 2-D bench configs, which
    start at N = 64): the cells of every level come from one closed form, so small N tests them all."""
    levels = tuple(n for n in cfg.mesh.refinements if n <= 16)[:2] or (16, 32)
    return dataclasses.replace(cfg, mesh=dataclasses.replace(cfg.mesh, refinements=levels),
                               output=dataclasses.replace(cfg.output, fields=False))


def measured(levels):
    """Every error a level records: its own norms and the reference, successive and Γ_C errors; and, for the
    data-only elastic studies (no exact solution), the contact force, measure and peak pressure."""
    names = ("L2", "H1", "_gc", "_ref", "diff_", "energy", "err", "contact_force", "contact_measure", "pressure_max")
    rows = []
    for level in levels:  # a refinement Level, or an ε-sweep Point (its `differences` to the VI solution)
        found = dict(getattr(level, "errors", None) or {})
        found.update({f"difference {k}": v for k, v in getattr(level, "differences", {}).items()})
        found.update({k: v for k, v in getattr(level, "extra", {}).items()
                      if isinstance(v, float) and any(s in k for s in names)})
        rows.append(found)
    return rows


GC_ERRORS = ("pos_gc", "L2_gc", "energy_err")
# the 3-D kinked rule's accuracy on triangles, where two partitions order a facet's vertices differently: ~1e-14
# for P1, ~1e-10 for P2 (problems/kinked.py), so 1e-9
SAME_GC_3D = 1e-9


def legacy_create(comm, dim, n, diagonal="right", ghost_mode=dolfinx.mesh.GhostMode.shared_facet):
    """meshes.build's mesh before grids.py: dolfinx's create_unit_*, serially with one part and no ghosts."""
    def one_part(comm, nparts, tdim, cells, ghost_mode):
        return dolfinx.graph.create_adjacencylist(np.zeros(cells.num_nodes, dtype=np.int32))
    options = dict(ghost_mode=dolfinx.mesh.GhostMode.none, partitioner=one_part) if comm.size == 1 else {}
    if dim == 2:
        return dolfinx.mesh.create_unit_square(comm, n, n, diagonal=getattr(dolfinx.mesh.DiagonalType, diagonal),
                                               **options)
    return dolfinx.mesh.create_unit_cube(comm, n, n, n, **options)


def compare_with_dolfinx_meshes(path, comm, monkeypatch):
    """Our meshes against dolfinx's own (the meshes of before), on the same communicator, with the
    degree-6 contact rule: the adaptive data rule of contact_quadrature: exact agrees with itself to ~1e-9
    only on N = 4 facets, so on 2 ranks, where the meshes are partitioned differently, it would compare the
    rule's round-off, not the meshes (the exact rule's own serial/2-rank agreement: tests/problems/test_contact.py)."""
    cfg = config.load(path)
    cfg = dataclasses.replace(small(cfg.map.studies[0] if cfg.study_type == "map" else cfg), contact_quadrature=6)
    ours = measured(studies.run_study(cfg, comm=comm))
    monkeypatch.setattr(grids, "create", legacy_create)
    theirs = measured(studies.run_study(cfg, comm=comm))
    assert len(ours) == len(theirs) >= len(cfg.mesh.levels)
    for mine, before in zip(ours, theirs):
        assert mine.keys() == before.keys() and mine
        for name in mine:
            floor = SAME_DIFFERENCE if name.startswith("difference") else 1e-300
            # 3-D Γ_C errors: the kinked rule on triangles is accurate to ~1e-10 for P2 (problems/kinked.py),
            # and two partitions order a facet's vertices differently
            rel = SAME_GC_3D if cfg.dimension == 3 and any(gc in name for gc in GC_ERRORS) else SAME
            assert mine[name] == pytest.approx(before[name], rel=rel, abs=floor), name


@pytest.mark.parametrize("path", shipped_built_in_configs())
def test_shipped_configs_same_errors_serial(path, monkeypatch):
    compare_with_dolfinx_meshes(path, MPI.COMM_SELF, monkeypatch)


@pytest.mark.mpi
@pytest.mark.parametrize("path", shipped_built_in_configs())
def test_shipped_configs_same_errors_parallel(path, monkeypatch):
    compare_with_dolfinx_meshes(path, MPI.COMM_WORLD, monkeypatch)


@pytest.mark.fast
@pytest.mark.parametrize("kind, diagonal", KINDS)
@pytest.mark.parametrize("comm", [pytest.param(MPI.COMM_SELF, id="serial"),
                                  pytest.param(MPI.COMM_WORLD, id="world", marks=pytest.mark.mpi)])
def test_cell_diameters_are_dolfinx_mesh_h(kind, diagonal, comm):
    # on a distorted grid (every cell its own diameter), bit for bit the numbers of dolfinx's mesh.h, which
    # meshes used before (and which builds the cell-to-cell connectivity cell_diameters avoids)
    dim = 2 if kind == "unit_square" else 3
    msh = grids.create(comm, dim, 5, diagonal)
    x = msh.geometry.x
    x[:, :dim] += 0.03 * np.sin(7 * x[:, :dim] + np.arange(dim))
    owned = np.arange(msh.topology.index_map(dim).size_local, dtype=np.int32)
    expected = dolfinx.cpp.mesh.h(msh._mesh, dim, owned)
    assert np.array_equal(meshes.cell_diameters(msh, chunk=7), expected)
    assert len(np.unique(np.concatenate(comm.allgather(expected)))) >= 10  # distorted: not the grid's one or two


@pytest.mark.fast
def test_kept_levels_are_built_once_per_family(make_config):
    """Within meshes.kept() (a map) a family's levels are built once and shared; a level of another family
    lets them go; outside, every build is a new mesh."""
    cfg = make_config()
    with meshes.kept():
        first = meshes.build(cfg.mesh, cfg.contact, 4, MPI.COMM_SELF)
        assert meshes.build(cfg.mesh, cfg.contact, 4, MPI.COMM_SELF) is first
        assert meshes.build(cfg.mesh, cfg.contact, 8, MPI.COMM_SELF) is not first
        other = meshes.build(cfg.mesh, "top", 4, MPI.COMM_SELF)
        assert other is not first and other.facets().size == first.facets().size
        assert meshes.build(cfg.mesh, cfg.contact, 4, MPI.COMM_SELF) is not first
    assert meshes.build(cfg.mesh, cfg.contact, 4, MPI.COMM_SELF) is not meshes.build(cfg.mesh, cfg.contact, 4,
                                                                                       MPI.COMM_SELF)
