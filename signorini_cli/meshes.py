"""Meshes of a refinement family, with Γ_C and Γ_D tagged, and their measured size h."""
from dataclasses import dataclass, field

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx.graph
import dolfinx.mesh
from dolfinx import cpp

CONTACT, DIRICHLET = 1, 2
# face name -> (axis, coordinate) on the unit square / cube
FACES = {"left": (0, 0.0), "right": (0, 1.0), "front": (1, 0.0), "back": (1, 1.0)}
FACES_2D = dict(FACES, bottom=(1, 0.0), top=(1, 1.0))
FACES_3D = dict(FACES, bottom=(2, 0.0), top=(2, 1.0))


@dataclass(frozen=True)
class Domain:
    """One level's mesh with its facet tags (CONTACT on Γ_C, DIRICHLET on Γ_D) and size."""
    mesh: dolfinx.mesh.Mesh
    facet_tags: dolfinx.mesh.MeshTagsMetaClass
    h: float
    h_min: float
    n: int
    columns: dict = field(default_factory=dict)  # the mesh's own per-level table columns (gmsh/file kinds)

    def facets(self, marker=CONTACT):
        """Local indices of the facets tagged `marker` (Γ_C by default; owned and ghost)."""
        return self.facet_tags.indices[self.facet_tags.values == marker]

    def ds_c(self, degree):
        """The UFL measure over Γ_C with a quadrature of this degree."""
        return ufl.Measure("ds", domain=self.mesh, subdomain_data=self.facet_tags,
                           metadata={"quadrature_degree": degree})(CONTACT)


def build(mesh_cfg, contact, n, comm=MPI.COMM_WORLD):
    """The level with `n` cells per side, Γ_C = the face named `contact`; for gmsh/file kinds `n` is
    the level's entry of mesh.levels and Γ_C the physical group named `contact`."""
    if mesh_cfg.kind in ("gmsh", "file"):
        from . import geometries  # imports meshes itself; gmsh is imported only on this branch
        return geometries.build(mesh_cfg, contact, n, comm)
    built_in = serial_options() if comm.size == 1 else {}
    if mesh_cfg.kind == "unit_square":
        diagonal = getattr(dolfinx.mesh.DiagonalType, mesh_cfg.diagonal)
        msh = dolfinx.mesh.create_unit_square(comm, n, n, diagonal=diagonal, **built_in)
        faces = FACES_2D
    else:
        msh = dolfinx.mesh.create_unit_cube(comm, n, n, n, **built_in)
        faces = FACES_3D
    tags = tag_boundary(msh, faces[contact])
    h, h_min = cell_sizes(msh)
    return Domain(msh, tags, h, h_min, n)


def serial_options():
    """On one rank, no graph partitioning and no ghost layer: dolfinx spends a third of building a
    built-in mesh on them (t_mesh in make bench). On several ranks its defaults stay: a partition it
    did not make itself leaves the vertices on the cut unshared in dolfinx 0.5.2."""
    def one_part(comm, nparts, tdim, cells, ghost_mode):
        return dolfinx.graph.create_adjacencylist(np.zeros(cells.num_nodes, dtype=np.int32))
    return dict(ghost_mode=dolfinx.mesh.GhostMode.none, partitioner=one_part)


def reference_domain(mesh_cfg, contact, refinements, comm=MPI.COMM_WORLD):
    """(Domain, nested): the finest level refined uniformly `refinements` more times, and whether every
    level of the family is nested in it (then moving a level onto it is exact)."""
    if mesh_cfg.kind in ("gmsh", "file"):
        from . import geometries
        return geometries.reference_domain(mesh_cfg, contact, refinements, comm)
    n = mesh_cfg.refinements[-1] * 2**refinements
    return build(mesh_cfg, contact, n, comm), not any(n % k for k in mesh_cfg.refinements)


def tag_boundary(msh, face):
    """Tag the facets on the plane x[axis] = value as CONTACT and every other exterior facet DIRICHLET."""
    axis, value = face
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    boundary = dolfinx.mesh.exterior_facet_indices(msh.topology)
    contact = dolfinx.mesh.locate_entities_boundary(msh, fdim, lambda x: np.isclose(x[axis], value))
    values = np.where(np.isin(boundary, contact), CONTACT, DIRICHLET).astype(np.int32)
    return dolfinx.mesh.meshtags(msh, fdim, boundary.astype(np.int32), values)


def cell_sizes(msh):
    """(largest, smallest) cell diameter over all ranks: the paper's h = max_K h_K."""
    tdim = msh.topology.dim
    cells = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    diameters = cpp.mesh.h(msh._mesh, tdim, cells)  # 0.5.2 wraps the C++ mesh in ._mesh
    local_max = diameters.max() if diameters.size else 0.0
    local_min = diameters.min() if diameters.size else np.inf
    return msh.comm.allreduce(local_max, op=MPI.MAX), msh.comm.allreduce(local_min, op=MPI.MIN)
