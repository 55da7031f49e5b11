"""The finite element: the one place that names the family and degree of the discrete spaces."""
from dolfinx import fem

FAMILY = "Lagrange"


def space(msh, degree=1, shape=None):
    """Continuous Lagrange of `degree` on msh: scalar, or vector-valued with shape (d,)."""
    if shape is None:
        return fem.FunctionSpace(msh, (FAMILY, degree))
    return fem.VectorFunctionSpace(msh, (FAMILY, degree), dim=shape[0])
