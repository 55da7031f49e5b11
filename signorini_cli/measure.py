"""Error norms against the exact solution, integrated with raised quadrature and MPI-reduced."""
import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import fem

ERROR_DEGREE = 8  # quadrature for u_h − u_ex: P1 error of a smooth u_ex, well above the rates' needs


def integrate(expr, measure):
    """∫ expr over `measure`, summed over ranks."""
    comm = measure.ufl_domain().ufl_cargo().comm
    return comm.allreduce(fem.assemble_scalar(fem.form(expr * measure)), op=MPI.SUM)


def errors(u_h, u_exact):
    """{'L2': ||u − u_h||_{L2(Ω)}, 'H1': |u − u_h|_{H1(Ω)} (the seminorm, as in the paper)}."""
    msh = u_h.function_space.mesh
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": ERROR_DEGREE})
    e = u_h - u_exact
    return {"L2": np.sqrt(abs(integrate(e**2, dx))),
            "H1": np.sqrt(abs(integrate(ufl.inner(ufl.grad(e), ufl.grad(e)), dx)))}
