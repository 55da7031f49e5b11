"""The tutorial-style dolfinx 0.5.2 script the whole `signorini run` is timed against: the demo
problem (2-D, alpha = 2, eps = h, u = sin(2 pi x)(1 - y)^2, contact on the bottom face) solved on N = 8 .. 512
as the FEniCSx tutorial writes a nonlinear problem and a convergence study: UFL forms with the positive part
as a conditional, dolfinx.nls.petsc.NewtonSolver with LU, errors through a degree-raised quadrature.

    python scripts/tutorial_baseline.py [N ...]      # prints N, L2, H1 per level and the total wall time
"""
import logging
import sys
import time

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import fem, mesh
from dolfinx.fem.petsc import NonlinearProblem
from dolfinx.nls.petsc import NewtonSolver

ALPHA, THETA = 2.0, 1.0


def solve(n):
    """(h, L2, H1, Newton iterations) of the level with n cells per side."""
    msh = mesh.create_unit_square(MPI.COMM_WORLD, n, n)
    V = fem.FunctionSpace(msh, ("Lagrange", 1))
    x = ufl.SpatialCoordinate(msh)
    u_ex = ufl.sin(2 * ufl.pi * x[0]) * (1 - x[1]) ** 2
    h = np.sqrt(2.0) / n
    eps = fem.Constant(msh, THETA * h)
    boundary = mesh.locate_entities_boundary(msh, 1, lambda p: np.isclose(p[1], 0.0))
    tags = mesh.meshtags(msh, 1, boundary, np.full(len(boundary), 1, dtype=np.int32))
    # the data quadrature of signorini's degree-6 rule, so that both solve nearly one discrete problem
    ds = ufl.Measure("ds", domain=msh, subdomain_data=tags, metadata={"quadrature_degree": 6})
    dx6 = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 6})
    dirichlet = mesh.locate_entities_boundary(  # left, right and top: every facet but the contact face's
        msh, 1, lambda p: np.isclose(p[0], 0.0) | np.isclose(p[0], 1.0) | np.isclose(p[1], 1.0))
    u_D = fem.Function(V)
    u_D.interpolate(fem.Expression(u_ex, V.element.interpolation_points()))
    bc = fem.dirichletbc(u_D, fem.locate_dofs_topological(V, 1, dirichlet))
    u, v = fem.Function(V), ufl.TestFunction(V)

    def positive(w):
        return ufl.conditional(ufl.gt(w, 0), w, 0)

    n_out = ufl.FacetNormal(msh)
    f = -ufl.div(ufl.grad(u_ex))
    g = eps * ufl.dot(ufl.grad(u_ex), n_out) + positive(u_ex) ** ALPHA
    F = (ufl.inner(ufl.grad(u), ufl.grad(v)) * ufl.dx - f * v * dx6
         + (positive(u) ** ALPHA - g) / eps * v * ds(1))
    problem = NonlinearProblem(F, u, bcs=[bc])
    newton = NewtonSolver(MPI.COMM_WORLD, problem)
    newton.rtol, newton.atol, newton.convergence_criterion = 1e-10, 1e-12, "incremental"
    ksp = newton.krylov_solver
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    its, _ = newton.solve(u)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 8})
    e = u - u_ex
    l2 = msh.comm.allreduce(fem.assemble_scalar(fem.form(e**2 * dx)), op=MPI.SUM)
    h1 = msh.comm.allreduce(fem.assemble_scalar(fem.form(ufl.inner(ufl.grad(e), ufl.grad(e)) * dx)), op=MPI.SUM)
    return h, np.sqrt(l2), np.sqrt(h1), its


def main(argv):
    logging.disable(logging.INFO)  # FFCx logs every JIT compilation at INFO
    sizes = [int(a) for a in argv] or [8, 16, 32, 64, 128, 256, 512]
    start = time.perf_counter()
    for n in sizes:
        h, l2, h1, its = solve(n)
        if MPI.COMM_WORLD.rank == 0:
            print(f"N={n:4d}  h={h:.3e}  L2={l2:.4e}  H1={h1:.4e}  newton={its}", flush=True)
    if MPI.COMM_WORLD.rank == 0:
        print(f"total {time.perf_counter() - start:.2f} s")
    PETSc.Sys.syncFlush()


if __name__ == "__main__":
    main(sys.argv[1:])
