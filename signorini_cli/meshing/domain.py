"""A level's mesh with Γ_C and Γ_D tagged and its measured size h: what every mesh kind hands on."""
from dataclasses import dataclass, field

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx.mesh
from dolfinx import cpp

CONTACT, DIRICHLET = 1, 2


@dataclass(frozen=True)
class Domain:
    """One level's mesh with its facet tags (CONTACT on Γ_C, DIRICHLET on Γ_D) and size."""
    mesh: dolfinx.mesh.Mesh
    facet_tags: dolfinx.mesh.MeshTagsMetaClass
    h: float
    h_min: float
    n: int
    columns: dict = field(default_factory=dict)  # the mesh's own per-level table columns (gmsh/file kinds)
    quadrature: tuple = None  # (data, errors): the Gauss degrees the level's data need, once checked (None: defaults)

    def facets(self, marker=CONTACT):
        """Local indices of the facets tagged `marker` (Γ_C by default; owned and ghost)."""
        return self.facet_tags.indices[self.facet_tags.values == marker]

    def ds_c(self, degree):
        """The UFL measure over Γ_C with a quadrature of this degree."""
        return ufl.Measure("ds", domain=self.mesh, subdomain_data=self.facet_tags,
                           metadata={"quadrature_degree": degree})(CONTACT)


def tag_facets(msh, is_contact):
    """Tag every exterior facet: CONTACT where is_contact(boundary facets) is True, else DIRICHLET."""
    fdim = msh.topology.dim - 1
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    boundary = dolfinx.mesh.exterior_facet_indices(msh.topology)
    values = np.where(is_contact(boundary), CONTACT, DIRICHLET).astype(np.int32)
    return dolfinx.mesh.meshtags(msh, fdim, boundary.astype(np.int32), values)


def facet_vertices(msh, facets):
    """(len(facets), d, 3): the vertex coordinates of each facet."""
    fdim = msh.topology.dim - 1
    if len(facets) == 0:
        return np.zeros((0, fdim + 1, 3))
    dofs = cpp.mesh.entities_to_geometry(msh._mesh, fdim, np.asarray(facets, dtype=np.int32), False)
    return msh.geometry.x[dofs]


def domain_of(msh, facet_tags, n):
    """The Domain of a tagged mesh, with h and h_min measured."""
    return Domain(msh, facet_tags, *cell_sizes(msh), n)


def cell_sizes(msh):
    """(largest, smallest) cell diameter over all ranks: the paper's h = max_K h_K."""
    diameters = cell_diameters(msh)
    local_max = diameters.max() if diameters.size else 0.0
    local_min = diameters.min() if diameters.size else np.inf
    return msh.comm.allreduce(local_max, op=MPI.MAX), msh.comm.allreduce(local_min, op=MPI.MIN)


def cell_diameters(msh, chunk=1 << 16):
    """The diameter (longest vertex-to-vertex distance) of each owned simplex, computed as dolfinx's
    mesh.h does, in chunks: mesh.h on cells would build the cell-to-cell connectivity (16 MiB at N = 1024)."""
    tdim = msh.topology.dim
    owned = msh.topology.index_map(tdim).size_local
    dofmap = msh.geometry.dofmap
    width = dofmap.offsets[1] if dofmap.num_nodes else tdim + 1  # a rank may own no cell of a tiny mesh
    vertices = dofmap.array.reshape(dofmap.num_nodes, width)[:owned, :tdim + 1]
    pairs = [(i, j) for i in range(tdim + 1) for j in range(i + 1, tdim + 1)]
    diameters = np.empty(owned)
    for start in range(0, owned, chunk):
        x = msh.geometry.x[vertices[start:start + chunk]]
        diameters[start:start + chunk] = np.max([np.sqrt(((x[:, i] - x[:, j]) ** 2).sum(axis=1)) for i, j in pairs],
                                                axis=0)
    return diameters
