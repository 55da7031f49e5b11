"""What the split assembly of a Newton solve needs beside the forms: the rows of J its varying part adds to
(kept as StoredRows, so that no second matrix of the level's size exists), the load part of a residual, and the
Dirichlet dofs as a mask."""
from dataclasses import dataclass

import numpy as np
import ufl
from petsc4py import PETSc

from dolfinx import fem, la


def varying_rows(V, a_vary, contact):
    """The owned rows (local indices) of J that its part beyond the stiffness can add to on any rank:
    the dofs of the cells of a_vary's facet integrals (Γ_C) and of the contact term's facets."""
    local = [] if contact is None else [contact.rows.ravel()]
    if a_vary is not None:
        cell_dofs = V.dofmap.list.array.reshape(V.dofmap.list.num_nodes, -1)
        for kind in a_vary.integral_types:
            for i in a_vary.integral_ids(kind):
                # cells, (cell, local facet) pairs, or (cell, facet, cell, facet) for interior facets
                entries = {fem.IntegralType.cell: 1, fem.IntegralType.exterior_facet: 2}.get(kind, 4)
                cells = np.asarray(a_vary.domains(kind, i)).reshape(-1, entries)[:, ::2]
                nodes = cell_dofs[cells.ravel()].ravel()  # a vector space's blocks: bs dofs per node
                local.append((V.dofmap.index_map_bs * nodes[:, None] + np.arange(V.dofmap.index_map_bs)).ravel())
    marks = la.vector(V.dofmap.index_map, V.dofmap.index_map_bs)  # owners learn of the rows others mark
    if local:
        marks.array[np.concatenate(local)] = 1.0
    marks.scatter_reverse(la.ScatterMode.add)
    owned = V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    return np.flatnonzero(marks.array[:owned] > 0).astype(np.int32)


@dataclass(frozen=True)
class StoredRows:
    """Some owned rows of an assembled matrix (global row numbers, CSR offsets, columns, values), to
    reset a matrix of the same pattern to them."""
    rows: np.ndarray
    offsets: np.ndarray
    columns: np.ndarray
    values: np.ndarray

    @classmethod
    def of(cls, A, local_rows):
        start = A.getOwnershipRange()[0]
        got = [A.getRow(start + int(r)) for r in local_rows]
        offsets = np.cumsum([0] + [len(columns) for columns, _ in got]).astype(PETSc.IntType)
        none = [np.zeros(0)]
        return cls((start + local_rows).astype(PETSc.IntType), offsets,
                   np.concatenate([columns for columns, _ in got] + none).astype(PETSc.IntType),
                   np.concatenate([values for _, values in got] + none).astype(PETSc.ScalarType))

    def reset(self, A):
        """A's stored rows := the stored values (INSERT, then flushed so that ADDs may follow). Collective."""
        if len(self.rows):
            A.setValuesIJV(self.offsets, self.columns, self.values, addv=PETSc.InsertMode.INSERT,
                           rowmap=self.rows)
        A.assemblyBegin(PETSc.Mat.AssemblyType.FLUSH)
        A.assemblyEnd(PETSc.Mat.AssemblyType.FLUSH)


def load_part(F):
    """The volume (cell) integrals of a residual form: load and stiffness, no boundary penalty."""
    return ufl.Form([itg for itg in F.integrals() if itg.integral_type() == "cell"])


def dirichlet_mask(V, bcs):
    """Bool mask over V's local dofs (ghosts included): True on the Dirichlet dofs of `bcs`."""
    index_map = V.dofmap.index_map
    mask = np.zeros((index_map.size_local + index_map.num_ghosts) * V.dofmap.index_map_bs, dtype=bool)
    for bc in bcs:
        mask[bc.dof_indices()[0]] = True
    return mask
