"""Moving a P1 function between meshes of one family (0.5.2 cannot interpolate across meshes).

The target's owned dof points are gathered on every rank, each rank evaluates the source where
its own cells contain them, and the lowest such rank's value wins (two allreduces). For nested
meshes every target vertex lies in a source cell on which the source is affine, so the transfer
is exact for P1."""
import numpy as np
from mpi4py import MPI

from dolfinx import fem, geometry


def transfer(u_source, V_target):
    """u_source (P1 on one mesh) as a Function on V_target (P1 on another mesh of the same domain)."""
    comm = V_target.mesh.comm
    index_map = V_target.dofmap.index_map
    n_owned = index_map.size_local
    points = V_target.tabulate_dof_coordinates()[:n_owned]
    counts = comm.allgather(n_owned)
    all_points = np.vstack(comm.allgather(points)) if sum(counts) else np.zeros((0, 3))
    values, found = evaluate(u_source, all_points)
    owner = np.where(found, comm.rank, comm.size).astype(np.int32)
    comm.Allreduce(MPI.IN_PLACE, owner, op=MPI.MIN)
    if np.any(owner == comm.size):
        missing = all_points[owner == comm.size][0]
        raise ValueError(f"transfer: {np.count_nonzero(owner == comm.size)} target points lie outside "
                         f"the source mesh, e.g. {missing}")
    values = np.where(owner == comm.rank, values, 0.0)
    comm.Allreduce(MPI.IN_PLACE, values, op=MPI.SUM)
    start = sum(counts[:comm.rank])
    u_target = fem.Function(V_target)
    u_target.x.array[:n_owned] = values[start:start + n_owned]
    u_target.x.scatter_forward()
    return u_target


def evaluate(u, points):
    """(values, found): u at `points` where a cell owned by this rank contains them, else (0, False)."""
    msh = u.function_space.mesh
    tdim = msh.topology.dim
    n_cells = msh.topology.index_map(tdim).size_local
    tree = geometry.BoundingBoxTree(msh, tdim, np.arange(n_cells, dtype=np.int32))
    colliding = geometry.compute_colliding_cells(msh, geometry.compute_collisions(tree, points), points)
    cells = np.full(len(points), -1, dtype=np.int32)
    for i in range(len(points)):
        links = colliding.links(i)
        if len(links):
            cells[i] = links[0]
    found = cells >= 0
    values = np.zeros(len(points))
    if np.any(found):
        values[found] = u.eval(points[found], cells[found])[:, 0]
    return values, found
