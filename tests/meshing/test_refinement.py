"""Uniform refinement carries Γ_C over: the point-in-facet test it rests on, and the tags of refined
built-in meshes against their coordinate tagging, serial and on 2 ranks."""
import numpy as np
import pytest
from mpi4py import MPI

import dolfinx.mesh
from signorini_cli.meshing import meshes, refinement
from signorini_cli.meshing.meshes import CONTACT

SEGMENT = np.array([[[0.0, 0.0, 0.0], [2.0, 1.0, 0.0]]])
TRIANGLE = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 2.0]]])


@pytest.mark.parametrize("simplices, point, inside", [
    pytest.param(SEGMENT, [0.5, 0.25, 0.0], True, id="segment-quarter"),
    pytest.param(SEGMENT, [1.5, 0.75, 0.0], True, id="segment-three-quarters"),
    pytest.param(SEGMENT, [0.5, 0.25 + 1e-6, 0.0], False, id="segment-off-line"),
    pytest.param(SEGMENT, [2.2, 1.1, 0.0], False, id="segment-beyond-end"),
    pytest.param(TRIANGLE, [1 / 3, 1 / 3, 4 / 3], True, id="triangle-centroid"),
    pytest.param(TRIANGLE, [1 / 6, 1 / 6, 7 / 6], True, id="triangle-corner-child"),
    pytest.param(TRIANGLE, [1 / 3, 1 / 3, 4 / 3 + 1e-6], False, id="triangle-off-plane"),
    pytest.param(TRIANGLE, [0.6, 0.6, 1.6], False, id="triangle-outside-edge"),
])
def test_in_simplices_cases(simplices, point, inside):
    # refined facets' centroids sit >= 1/6 inside (barycentric) their parent facet; 1e-6 off is far
    # beyond the 1e-8 relative tolerance, which only absorbs round-off
    assert refinement.in_simplices(np.array([point]), simplices).tolist() == [inside]


def test_in_simplices_empty():
    assert refinement.in_simplices(np.zeros((3, 3)), np.zeros((0, 2, 3))).tolist() == [False] * 3


def check_refined_tags_match_coordinates(comm, make, face):
    coarse = make(comm)
    domain = meshes.Domain(coarse, meshes.tag_boundary(coarse, face), *meshes.cell_sizes(coarse), 0)
    refined = refinement.refine(domain)
    expected = meshes.tag_boundary(refined.mesh, face)  # the coordinate tagging of the fine mesh
    mine = dict(zip(refined.facet_tags.indices, refined.facet_tags.values))
    theirs = dict(zip(expected.indices, expected.values))
    assert comm.allreduce(mine == theirs, op=MPI.LAND)
    n_contact = comm.allreduce(int(np.sum(refined.facet_tags.values == CONTACT)), op=MPI.SUM)
    assert n_contact > 0


CASES = [
    pytest.param(lambda comm: dolfinx.mesh.create_unit_square(comm, 3, 5), meshes.FACES_2D["bottom"], id="2d"),
    pytest.param(lambda comm: dolfinx.mesh.create_unit_cube(comm, 2, 3, 2), meshes.FACES_3D["left"], id="3d"),
]


@pytest.mark.parametrize("make, face", CASES)
def test_refine_tags_match_coordinates(make, face):
    check_refined_tags_match_coordinates(MPI.COMM_WORLD, make, face)


@pytest.mark.mpi
@pytest.mark.parametrize("make, face", CASES)
def test_refine_tags_match_coordinates_two_ranks(make, face):
    assert MPI.COMM_WORLD.size == 2
    check_refined_tags_match_coordinates(MPI.COMM_WORLD, make, face)
