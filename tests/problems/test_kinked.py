"""The kinked rule on triangles: its integrals equal the same integrals over the facets cut into many small
triangles (where every kink is nearly straight), to round-off."""
import numpy as np
from mpi4py import MPI

from signorini_cli.problems import kinked, measure


# the four children of a triangle (midpoint subdivision), their vertices in the parent's barycentric coordinates
CHILDREN = np.array([[[1, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5]], [[0.5, 0.5, 0], [0, 1, 0], [0, 0.5, 0.5]],
                     [[0.5, 0, 0.5], [0, 0.5, 0.5], [0, 0, 1]], [[0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]]])


def subdivided(points, values, levels):
    """The triangles (M 4^levels, 3, 3) of `levels` midpoint subdivisions, with a P1 (values (M, 3) at the
    vertices) or P2 trace (values (M, 6) at kinked.P2_NODES) restricted to them."""
    def basis(child):  # the parent's basis at the child's dof points
        return child if values.shape[1] == 3 else measure.p2_basis(kinked.P2_NODES @ child)
    for _ in range(levels):
        points = np.concatenate([np.einsum("vk,mkx->mvx", child, points) for child in CHILDREN])
        values = np.concatenate([np.einsum("qj,mj->mq", basis(child), values) for child in CHILDREN])
    return points, values


def face_triangles(n):
    """The face z = 0 of the unit cube cut into n × n × 2 triangles (the cube study's face at N = n)."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    corner = np.stack((i.ravel(), j.ravel()), axis=1) / n
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) / n
    points = np.zeros((2 * n * n, 3, 3))
    points[:, :, :2] = np.concatenate([corner[:, None] + square[[0, 1, 2]], corner[:, None] + square[[0, 2, 3]]])
    return points


def w(facets, x):
    """The exact trace the Γ_C error tests compare with."""
    return np.sin(2 * np.pi * x[..., 0]) * np.sin(np.pi * x[..., 1])


def test_curved_kink_tangent_to_the_lines():
    """[k]_+³ with k = sin 3x + cos 2.5y − 1.2 on one large triangle, whose zero curve is tangent to the rule's
    lines inside it: measured 1.2e-15 relative to the 4³ and 4⁴ subdivisions (which agree to 1e-15); 1.1e-7
    before such tangent points of a non-polynomial kink were breaks."""
    points = np.zeros((1, 3, 3))
    points[0, :, :2] = [[0.96165719, 0.72478994], [0.54122686, 0.2768912], [0.16065201, 0.96992541]]

    def kink(facets, lam, x):
        return np.sin(3 * x[..., 0]) + np.cos(2.5 * x[..., 1]) - 1.2

    def integrand(facets, lam, x):
        return np.maximum(kink(facets, lam, x), 0) ** 3
    kinks = [(kink, kinked.SEARCH[1])]  # searched as the zeros of u − u_h of a P1 trace are
    one = kinked.on_facets(points, integrand, kinks).sum()
    fine, finer = (kinked.on_facets(subdivided(points, np.zeros((1, 3)), n)[0], integrand, kinks).sum()
                   for n in (3, 4))
    assert abs(fine / finer - 1) < 1e-14 and abs(one / finer - 1) < 1e-13


def test_gamma_c_errors_of_a_p1_trace_on_triangles():
    """L2_gc and pos_gc (α = 2) of a P1 w_h against w = sin 2πx sin πy on the face z = 0 of the unit cube cut
    into 8 × 8 × 2 triangles (the cube study's N = 8 face; w_h: w at the vertices moved by 0.01 cos(7x + 3y)):
    the zero curves of w and w − w_h are tangent to the lines and cross w_h's zero line inside facets. Measured
    against the 4² and 4³ subdivisions (which agree to 1e-15): 2e-16 and 7e-16 relative; pos_gc 7.1e-11 before
    those points were breaks."""
    points = face_triangles(8)
    w_h = w(None, points) + 0.01 * np.cos(7 * points[..., 0] + 3 * points[..., 1])

    def errors(levels):
        found = measure.contact_errors(MPI.COMM_SELF, *subdivided(points, w_h, levels), w, 1.0, 2.0, 0.0)
        return np.array([found["L2_gc"], found["pos_gc"]])
    one, fine, finer = errors(0), errors(2), errors(3)
    assert np.all(np.abs(fine / finer - 1) < 1e-14) and np.all(np.abs(one / finer - 1) < 1e-13)


def test_no_facets():
    """A rank without Γ_C facets (2 ranks, the contact face on the other): empty integrals, whatever the kinks."""
    def kink(facets, lam, x):
        return np.sin(x[..., 0]) - 0.5

    def integrand(facets, lam, x):
        return np.maximum(kink(facets, lam, x), 0) ** 3
    trace = measure.on_facets(np.zeros((0, 3)))
    found = kinked.on_facets(np.zeros((0, 3, 3)), integrand, [trace, (kink, kinked.SEARCH[1])])
    assert found.shape == (0,)


def test_gamma_c_errors_of_a_p2_trace_on_triangles():
    """As the P1 test, for a P2 w_h (w at the P2 nodes moved by 0.01 cos(7x + 3y)): its zero conics and the
    zero curves of w − w_h have several branches per facet and pairs of zeros close together along the lines.
    Measured against the 4² subdivisions (which agree with the 4³ to 2e-15): 2e-16 and 1.6e-15 relative; pos_gc
    4.0e-13 with 8 samples per line and tangents sought over triangles of size 1/2."""
    points = face_triangles(8)
    nodes = np.einsum("qk,mkx->mqx", kinked.P2_NODES, points)
    w_h = w(None, nodes) + 0.01 * np.cos(7 * nodes[..., 0] + 3 * nodes[..., 1])

    def errors(levels):
        found = measure.contact_errors(MPI.COMM_SELF, *subdivided(points, w_h, levels), w, 1.0, 2.0, 0.0)
        return np.array([found["L2_gc"], found["pos_gc"]])
    assert np.all(np.abs(errors(0) / errors(2) - 1) < 1e-14)
