"""The transfer between levels is exact for P1 on nested meshes, serial and on 2 ranks."""
import numpy as np
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem, mesh
from signorini_cli.transfer import transfer

MESHES = [
    pytest.param(lambda comm, n: mesh.create_unit_square(comm, n, n), id="2d"),
    pytest.param(lambda comm, n: mesh.create_unit_cube(comm, n, n, n), id="3d"),
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
