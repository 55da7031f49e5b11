"""Meshes of a refinement family, with Γ_C and Γ_D tagged, and their measured size h: the built-in grids
(grids.py, built in place on every rank) and the gmsh/file kinds (geometries.py)."""
import contextlib

import numpy as np
from mpi4py import MPI

import dolfinx.mesh

from . import geometries, grids
from .domain import (CONTACT, DIRICHLET, Domain, cell_diameters, cell_sizes,  # noqa: F401 (the stage's names)
                     domain_of, facet_vertices, tag_facets)

# face name -> (axis, coordinate) on the unit square / cube
FACES = {"left": (0, 0.0), "right": (0, 1.0), "front": (1, 0.0), "back": (1, 1.0)}
FACES_2D = dict(FACES, bottom=(1, 0.0), top=(1, 1.0))
FACES_3D = dict(FACES, bottom=(2, 0.0), top=(2, 1.0))


_kept = None  # within kept(): (family, {n: Domain}) of the last family built


@contextlib.contextmanager
def kept():
    """Within: the levels of one family (mesh config, Γ_C, communicator) are built once and shared, as
    the points of a map solve on the same meshes; a level of another family lets the kept ones go."""
    global _kept
    _kept = (None, {})
    try:
        yield
    finally:
        _kept = None


def build(mesh_cfg, contact, n, comm=MPI.COMM_WORLD):
    """The level with `n` cells per side, Γ_C = the face named `contact`; for gmsh/file kinds `n` is
    the level's entry of mesh.levels and Γ_C the physical group named `contact`."""
    global _kept
    if _kept is None:
        return _build(mesh_cfg, contact, n, comm)
    family = (mesh_cfg, contact, comm)
    if _kept[0] != family:
        _kept = (family, {})
    levels = _kept[1]
    if n not in levels:
        levels[n] = _build(mesh_cfg, contact, n, comm)
    return levels[n]


def _build(mesh_cfg, contact, n, comm):
    if mesh_cfg.kind in ("gmsh", "file"):
        return geometries.build(mesh_cfg, contact, n, comm)
    dim = 2 if mesh_cfg.kind == "unit_square" else 3
    # one rank: no ghost layer (nothing to share); several: dolfinx's default, ghosts across facets
    ghost_mode = dolfinx.mesh.GhostMode.none if comm.size == 1 else dolfinx.mesh.GhostMode.shared_facet
    msh = grids.create(comm, dim, n, mesh_cfg.diagonal, ghost_mode)
    tags = tag_boundary(msh, (FACES_2D if dim == 2 else FACES_3D)[contact])
    return domain_of(msh, tags, n)


def kuhn(mesh_cfg):
    """Whether the family's meshes are Kuhn grids of [0, 1]^d (every simplex a chain of unit steps from a
    grid point): the unit cube, the unit square with diagonal 'right'."""
    return mesh_cfg.kind == "unit_cube" or (mesh_cfg.kind == "unit_square" and mesh_cfg.diagonal == "right")


def tag_boundary(msh, face):
    """Tag the facets on the plane x[axis] = value as CONTACT and every other exterior facet DIRICHLET
    (from the exterior facets' vertices: dolfinx's locate_entities_boundary would also build the
    vertex-to-cell connectivity, 28 MiB at N = 1024 that nothing else needs)."""
    axis, value = face
    return tag_facets(msh, lambda boundary: np.isclose(facet_vertices(msh, boundary)[..., axis], value).all(axis=1))
