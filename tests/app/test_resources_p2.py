"""The memory estimate of a P2 study counts P2's dofs and Jacobian nonzeros, not P1's."""
import pytest
import ufl
from mpi4py import MPI

from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from signorini_cli.app import resources
from signorini_cli.meshing import meshes
from signorini_cli.problems import element


@pytest.mark.parametrize("dim, n, rel", [(2, 32, 0.1), (3, 16, 0.2)])
def test_p2_estimate_counts_p2_dofs_and_nonzeros(make_config, dim, n, rel):
    """Against the assembled P2 stiffness on the finest level: within 10 % in 2-D, 20 % in 3-D (the estimate
    counts a dof per vertex and per edge of an unbounded grid; the boundary has fewer neighbours, a share
    falling like 1/N: in 3-D at N = 16 the estimate is 9 % over in dofs, 15 % in nonzeros)."""
    mesh = {"kind": "unit_square" if dim == 2 else "unit_cube", "refinements": [n // 2, n]}
    cfg = make_config(element={"degree": 2}, dimension=dim, mesh=mesh)
    ((_, dofs, nonzeros),) = resources.peak_meshes(cfg, MPI.COMM_SELF)
    V = element.space(meshes.build(cfg.mesh, cfg.contact, n, MPI.COMM_SELF).mesh, 2)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    A = fem_petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx))
    A.assemble()
    assert dofs == pytest.approx(V.dofmap.index_map.size_global, rel=rel)
    assert nonzeros == pytest.approx(A.getInfo()["nz_used"], rel=rel)


ELASTIC = {"problem": {"pde": "elasticity", "exact": ["0.1*sin(pi*x)*y", "0.1*cos(2*pi*x)*(1 - y)**2"]},
           "mesh": {"refinements": [16, 32]}}


@pytest.mark.parametrize("degree", [1, 2])
def test_vector_estimate_counts_d_components(make_config, degree):
    """Elasticity in 2-D: d = 2 dofs per node and 2 × 2 Jacobian blocks, against the assembled vector
    stiffness on the finest level within 10 % (the estimate's unbounded grid, as for the scalar space)."""
    cfg = make_config(element={"degree": degree}, **ELASTIC)
    ((_, dofs, nonzeros),) = resources.peak_meshes(cfg, MPI.COMM_SELF)
    V = element.space(meshes.build(cfg.mesh, cfg.contact, 32, MPI.COMM_SELF).mesh, degree, shape=(2,))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    A = fem_petsc.assemble_matrix(fem.form(ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx))
    A.assemble()
    assert dofs == pytest.approx(V.dofmap.index_map.size_global * V.dofmap.index_map_bs, rel=0.1)
    assert nonzeros == pytest.approx(A.getInfo()["nz_used"], rel=0.1)
