"""The finite element: the one place that names the family (Lagrange on simplices) and what depends on
its degree (the quadrature that integrates an error or a product of two discrete functions)."""
from dolfinx import fem

FAMILY = "Lagrange"


def space(msh, degree, shape=None):
    """Continuous Lagrange of `degree` on msh: scalar, or vector-valued with shape=(d,)."""
    if shape is None:
        return fem.FunctionSpace(msh, (FAMILY, degree))
    return fem.VectorFunctionSpace(msh, (FAMILY, degree), dim=shape[0])


def degree_of(V):
    """The polynomial degree of V's element."""
    return V.ufl_element().degree()


def product_degree(degree):
    """Quadrature exact for ∫ u v and ∫ ∇u·∇v of two functions of this degree on affine simplices."""
    return 2 * degree


# The error u_h − u_ex of a smooth u_ex, by element degree: (coarse, fine) quadrature and the h below which
# the fine one is used. P1: against degree 12 on the bench problems (u_ex = sin(2 pi x)(1-y)^2,
# sin(2 pi x) sin(pi y)(1-z)^2) degree 6 moves L2 and H1 by at most 1.6e-11 relative in 2-D (N = 64,
# h = 0.022; 3.2e-12 at N = 1024) and 6.0e-11 in 3-D (N = 64, h = 0.027), degree 8 by up to 8.5e-13
# (round-off); in 3-D degree 6 moves L2 by 9.9e-10 at N = 32 (h = 0.054) and 1.6e-8 at N = 16, hence 8 on
# coarser levels. P2 two more: against degree 16 on the 2-D bench problem (its P2 solutions, N = 8 .. 128)
# degree 10 moves L2 by at most 1.6e-10 relative (N = 8) and H1 by 6e-13, degree 8 (N = 64, 128) both by
# at most 1.9e-11. P2 in 3-D: against degree 18 on a 3-D elastic P2 solution (u_ex = (0.1 sin(pi x) z,
# 0.05 sin(pi y) z, 0.1 cos(2 pi x) cos(pi y)(1-z)^2), N = 2, 4, 8) degree 10 moves L2 by up to 4.6e-7 (N = 2);
# degree 14 by 8.5e-11 (N = 2, h = 0.87) and 7e-14 (N = 4), degree 12 by 9.5e-11 (N = 4) and 9.4e-13 (N = 8,
# h = 0.22). By degree, or by (degree, dimension) where the dimension needs its own.
ERROR_DEGREES = {1: (8, 6, 0.03), 2: (10, 8, 0.03), (2, 3): (14, 12, 0.3)}


def error_degree(degree, h, dim):
    """The quadrature degree of the error integrals of an element of `degree` on a dim-D mesh of size h."""
    coarse, fine, fine_h = ERROR_DEGREES.get((degree, dim), ERROR_DEGREES[degree])
    return fine if h <= fine_h else coarse
