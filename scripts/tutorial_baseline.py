"""The tutorial-style dolfinx 0.5.2 scripts the whole `signorini run` is timed against: the demo problem (2-D,
alpha = 2, eps = h, u = sin(2 pi x)(1 - y)^2, contact on the bottom face) solved on N = 8 .. 512 as the FEniCSx
tutorial writes a nonlinear problem and a convergence study: UFL forms with the exact positive part as a
`ufl.conditional`, Newton from u = 0 on every level, errors through a degree-raised quadrature.

    python scripts/tutorial_baseline.py [--solver amg|lu] [--nested] [N ...]

`--solver amg` (the default, the reference of `make bench`): PETSc SNES Newton with CG + BoomerAMG, as the
tutorial sets up a Krylov solver through PETSc options; `--solver lu`: dolfinx's NewtonSolver with MUMPS LU;
`--nested`: each level starts from the previous level's solution, evaluated at the new dofs (nested iteration).
Prints N, L2, H1 and Newton iterations per level and the total wall time."""
import argparse
import logging
import time

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import fem, geometry, mesh
from dolfinx.fem.petsc import NonlinearProblem, create_matrix, create_vector
from dolfinx.nls.petsc import NewtonSolver

ALPHA, THETA = 2.0, 1.0
# the precision the package solves to: Newton to ||F|| <= 1e-10 relative / 1e-12 absolute, CG to 1e-10
SNES_OPTIONS = {"snes_type": "newtonls", "snes_rtol": 1e-10, "snes_atol": 1e-12, "ksp_type": "cg",
                "ksp_rtol": 1e-10, "pc_type": "hypre", "pc_hypre_type": "boomeramg"}


def level_problem(n):
    """(mesh, u, NonlinearProblem, u_ex) of the level with n cells per side."""
    msh = mesh.create_unit_square(MPI.COMM_WORLD, n, n)
    V = fem.FunctionSpace(msh, ("Lagrange", 1))
    x = ufl.SpatialCoordinate(msh)
    u_ex = ufl.sin(2 * ufl.pi * x[0]) * (1 - x[1]) ** 2
    eps = fem.Constant(msh, THETA * np.sqrt(2.0) / n)
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
    return msh, u, NonlinearProblem(F, u, bcs=[bc]), u_ex


def solve_snes(msh, u, problem):
    """SNES Newton with CG + BoomerAMG (PETSc options under a prefix, as the tutorial sets a KSP up)."""
    b, A = create_vector(problem.L), create_matrix(problem.a)

    def residual(snes, x, F):
        x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        x.copy(u.vector)
        u.x.scatter_forward()
        problem.F(x, F)

    def jacobian(snes, x, J, P):
        problem.J(x, J)

    snes = PETSc.SNES().create(msh.comm)
    snes.setFunction(residual, b)
    snes.setJacobian(jacobian, A)
    opts = PETSc.Options()
    for key, value in SNES_OPTIONS.items():
        opts[f"tutorial_{key}"] = value
    snes.setOptionsPrefix("tutorial_")
    snes.setFromOptions()
    x = u.vector.copy()
    snes.solve(None, x)
    x.copy(u.vector)
    u.x.scatter_forward()
    its = snes.getIterationNumber()
    for obj in (snes, b, A, x):
        obj.destroy()
    return its


def solve_lu(msh, u, problem):
    """dolfinx's NewtonSolver with MUMPS LU, the tutorial's nonlinear Poisson set-up."""
    newton = NewtonSolver(msh.comm, problem)
    newton.rtol, newton.atol, newton.convergence_criterion = 1e-10, 1e-12, "incremental"
    ksp = newton.krylov_solver
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    its, _ = newton.solve(u)
    return its


def nested_guess(u, previous):
    """u := the previous level's solution at u's dofs (point evaluation on the coarser mesh, serial)."""
    coarse = previous.function_space.mesh
    points = u.function_space.tabulate_dof_coordinates()
    tree = geometry.BoundingBoxTree(coarse, coarse.topology.dim)
    cells = geometry.compute_colliding_cells(coarse, geometry.compute_collisions(tree, points), points)
    first = np.array([cells.links(i)[0] for i in range(len(points))], dtype=np.int32)
    u.x.array[:] = previous.eval(points, first)[:, 0]


def errors(msh, u, u_ex):
    """(L2, H1 seminorm) of u - u_ex with a degree-8 quadrature."""
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": 8})
    e = u - u_ex
    l2 = msh.comm.allreduce(fem.assemble_scalar(fem.form(e**2 * dx)), op=MPI.SUM)
    h1 = msh.comm.allreduce(fem.assemble_scalar(fem.form(ufl.inner(ufl.grad(e), ufl.grad(e)) * dx)), op=MPI.SUM)
    return np.sqrt(l2), np.sqrt(h1)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--solver", choices=("amg", "lu"), default="amg")
    parser.add_argument("--nested", action="store_true")
    parser.add_argument("sizes", nargs="*", type=int, default=[8, 16, 32, 64, 128, 256, 512])
    args = parser.parse_args(argv)
    logging.disable(logging.INFO)  # FFCx logs every JIT compilation at INFO
    start, previous = time.perf_counter(), None
    for n in args.sizes:
        msh, u, problem, u_ex = level_problem(n)
        if args.nested and previous is not None:
            nested_guess(u, previous)
        its = (solve_snes if args.solver == "amg" else solve_lu)(msh, u, problem)
        l2, h1 = errors(msh, u, u_ex)
        previous = u
        if MPI.COMM_WORLD.rank == 0:
            print(f"N={n:4d}  L2={l2:.6e}  H1={h1:.6e}  newton={its}", flush=True)
    if MPI.COMM_WORLD.rank == 0:
        print(f"total {time.perf_counter() - start:.2f} s")


if __name__ == "__main__":
    main()
