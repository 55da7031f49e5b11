"""The transfer between levels is exact for P1 on nested meshes, serial and on 2 ranks."""
import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem, mesh
from signorini_cli.meshing import grids
from signorini_cli.solve.transfer import (GridValues, evaluate, evaluate_routed, kuhn_grid, kuhn_transfer, needed_layers,
                                          transfer)

MESHES = [
    pytest.param(lambda comm, n: mesh.create_unit_square(comm, n, n), id="2d"),
    pytest.param(lambda comm, n: mesh.create_unit_cube(comm, n, n, n), id="3d"),
    # the built-in meshes as meshes.build makes them (slabs per rank): Kuhn fast path and searched path
    pytest.param(lambda comm, n: grids.create(comm, 2, n, "right"), id="grid-2d-right"),
    pytest.param(lambda comm, n: grids.create(comm, 2, n, "left"), id="grid-2d-left"),
    pytest.param(lambda comm, n: grids.create(comm, 2, n, "crossed"), id="grid-2d-crossed"),
    pytest.param(lambda comm, n: grids.create(comm, 3, n), id="grid-3d"),
]


def p1_function(msh):
    """A P1 interpolant of a smooth function: not in any coarser space of the family."""
    V = fem.FunctionSpace(msh, ("Lagrange", 1))
    u = fem.Function(V)
    u.interpolate(lambda x: np.sin(3 * x[0]) * np.exp(x[1]) + x[2] ** 2)
    return u


def integral(expr, msh):
    return msh.comm.allreduce(fem.assemble_scalar(fem.form(expr * ufl.dx(domain=msh))), op=MPI.SUM)


def check_nested_exact(make):
    comm = MPI.COMM_WORLD
    coarse = p1_function(make(comm, 4))
    moved = transfer(coarse, fem.FunctionSpace(make(comm, 8), ("Lagrange", 1)))
    # The same function on both meshes has the same L2 norm and H1 seminorm (integrated exactly:
    # degree-2 integrands of P1 functions); 1e-12 relative is round-off in the assembly sums.
    # A non-nested pair (4 -> 6 cells) misses the H1 equality by 5%.
    for form in (lambda f: f**2, lambda f: ufl.inner(ufl.grad(f), ufl.grad(f))):
        assert integral(form(moved), moved.function_space.mesh) == pytest.approx(
            integral(form(coarse), coarse.function_space.mesh), rel=1e-12)
    # and moving it back reproduces the coarse dofs (coarse vertices are fine vertices)
    back = transfer(moved, coarse.function_space)
    assert integral((back - coarse) ** 2, coarse.function_space.mesh) < 1e-26


@pytest.mark.parametrize("make", MESHES)
def test_transfer_nested_exact_serial(make):
    check_nested_exact(make)


@pytest.mark.mpi
@pytest.mark.parametrize("make", MESHES)
def test_transfer_nested_exact_two_ranks(make):
    assert MPI.COMM_WORLD.size == 2
    check_nested_exact(make)


def check_extend_outside(comm):
    """An affine source is its own affine extension: moved onto a mesh that reaches beyond the source
    (as the finer mesh of a curved family does) it stays exact; without extend it is an error."""
    source = fem.Function(fem.FunctionSpace(mesh.create_unit_square(comm, 4, 4), ("Lagrange", 1)))
    source.interpolate(lambda x: 1 + 2 * x[0] + 3 * x[1])
    wider = mesh.create_rectangle(comm, [np.array([-0.1, 0.0]), np.array([1.1, 1.05])], [6, 5])
    V = fem.FunctionSpace(wider, ("Lagrange", 1))
    with pytest.raises(ValueError, match="lie outside the source mesh"):
        transfer(source, V)
    moved = transfer(source, V, extend=True)
    exact = fem.Function(V)
    exact.interpolate(lambda x: 1 + 2 * x[0] + 3 * x[1])
    # round-off of the pull-back: observed 9e-16
    assert comm.allreduce(np.max(np.abs(moved.x.array - exact.x.array)), op=MPI.MAX) < 1e-12


def test_transfer_extend_outside_serial():
    check_extend_outside(MPI.COMM_SELF)


@pytest.mark.mpi
def test_transfer_extend_outside_two_ranks():
    assert MPI.COMM_WORLD.size == 2
    check_extend_outside(MPI.COMM_WORLD)


def check_kuhn_fast_path(comm):
    """The closed-form P1 interpolant on the built-in Kuhn grids is the source itself at any point:
    it matches point evaluation (search in the source's cells) also on a non-nested target."""
    for make, coarse_n, fine_n in ((lambda n: mesh.create_unit_square(comm, n, n), 8, 12),
                                   (lambda n: mesh.create_unit_cube(comm, n, n, n), 4, 6),
                                   (lambda n: grids.create(comm, 2, n, "right"), 8, 12),
                                   (lambda n: grids.create(comm, 3, n), 4, 6)):
        coarse = p1_function(make(coarse_n))
        assert kuhn_grid(coarse.function_space.mesh) == coarse_n
        V_fine = fem.FunctionSpace(make(fine_n), ("Lagrange", 1))
        fast = kuhn_transfer(coarse, coarse_n, V_fine)
        owned = V_fine.dofmap.index_map.size_local
        points = np.vstack(comm.allgather(V_fine.tabulate_dof_coordinates()[:owned]))
        values, found = evaluate(coarse, points)
        count, summed = found.astype(np.int32), np.where(found, values, 0.0)
        comm.Allreduce(MPI.IN_PLACE, count, op=MPI.SUM)
        comm.Allreduce(MPI.IN_PLACE, summed, op=MPI.SUM)
        searched = summed / count.clip(1)  # points on a rank boundary are found twice, with one value
        start = sum(comm.allgather(owned)[:comm.rank])
        assert np.all(count >= 1)
        # round-off of two evaluations of one affine function per cell
        assert np.abs(fast.x.array[:owned] - searched[start:start + owned]).max() < 1e-13


def check_grid_values(comm):
    """A P1 function given by its grid values alone, all of them on rank 0 (a resumed study's stored u_h),
    moves as the function on its mesh does: the same numbers, scalar and vector."""
    for dim, coarse_n, fine_n, space in ((2, 4, 8, fem.FunctionSpace), (3, 2, 4, fem.VectorFunctionSpace)):
        V = space(grids.create(comm, dim, coarse_n), ("Lagrange", 1))
        u = fem.Function(V)
        u.interpolate(lambda x: np.vstack([np.sin(3 * x[0] + k) * np.exp(x[1]) + x[2] ** 2
                                           for k in range(V.dofmap.index_map_bs)]))
        owned, bs = V.dofmap.index_map.size_local, V.dofmap.index_map_bs
        points = np.vstack(comm.allgather(V.tabulate_dof_coordinates()[:owned]))
        values = np.vstack(comm.allgather(u.x.array.reshape(-1, bs)[:owned]))
        held = len(points) if comm.rank == 0 else 0
        V_fine = space(grids.create(comm, dim, fine_n), ("Lagrange", 1))
        moved = transfer(GridValues(coarse_n, points[:held], values[:held]), V_fine)
        assert np.array_equal(moved.x.array, transfer(u, V_fine).x.array)


def test_grid_values_serial():
    check_grid_values(MPI.COMM_WORLD)


@pytest.mark.mpi
def test_grid_values_two_ranks():
    assert MPI.COMM_WORLD.size == 2
    check_grid_values(MPI.COMM_WORLD)


def test_kuhn_fast_path_serial():
    check_kuhn_fast_path(MPI.COMM_WORLD)


@pytest.mark.mpi
def test_kuhn_fast_path_two_ranks():
    assert MPI.COMM_WORLD.size == 2
    check_kuhn_fast_path(MPI.COMM_WORLD)


@pytest.mark.parametrize("diagonal", ["left", "crossed"])
def test_kuhn_grid_only_for_kuhn_triangulations(diagonal):
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 8, 8, diagonal=getattr(mesh.DiagonalType, diagonal))
    assert kuhn_grid(msh) == 0  # these take the searched path, exact on nested meshes as above
    assert kuhn_grid(mesh.create_rectangle(MPI.COMM_WORLD, [np.zeros(2), np.array([2.0, 1.0])], [8, 4])) == 0


@pytest.mark.parametrize("points, layers", [
    (np.zeros((0, 2)), (0, -1)),                      # no targets: no layer
    (np.array([[0.1, 0.0], [0.9, 0.3]]), (0, 3)),    # n = 8: y = 0.3 lies in cell row 2, read up to row 3
    (np.array([[0.5, 1.0]]), (7, 8)),                # the top edge belongs to the last cell row, 7
    (np.array([[0.5, 0.5, 0.25]]), (2, 3)),          # 3-D: the last axis is z
])
def test_needed_layers(points, layers):
    assert needed_layers(points, 8) == layers


@pytest.mark.mpi
def test_kuhn_transfer_reads_only_its_layers():
    """On 2 ranks of slabs no rank needs the whole coarse grid (17 layers at N = 16), only its half."""
    comm = MPI.COMM_WORLD
    coarse = p1_function(grids.create(comm, 2, 16, "right"))
    V_fine = fem.FunctionSpace(grids.create(comm, 2, 32, "right"), ("Lagrange", 1))
    first, last = needed_layers(V_fine.tabulate_dof_coordinates()[:, :2], 16)
    assert last - first + 1 <= 8 + 1 + 2  # 8 cell rows of its slab + the ghost row + the top row's points
    owned = V_fine.dofmap.index_map.size_local
    searched, found = evaluate_routed(coarse, V_fine.tabulate_dof_coordinates()[:owned])
    assert found.all()
    # round-off of two evaluations of one affine function per cell
    assert np.abs(kuhn_transfer(coarse, 16, V_fine).x.array[:owned] - searched).max() < 1e-13
