"""Moving a P1 function between meshes of one family (0.5.2 cannot interpolate across meshes).

The target's owned dof points are gathered on every rank, each rank evaluates the source where
its own cells contain them, and the lowest such rank's value wins (two allreduces). For nested
meshes every target vertex lies in a source cell on which the source is affine, so the transfer
is exact for P1. A source on the built-in Kuhn grid of the unit square ('right' diagonal) or cube
takes a fast path: its vertex values are gathered into the grid on every rank and the P1 interpolant
is evaluated in closed form (the same values, no search)."""
import numpy as np
from mpi4py import MPI

from dolfinx import fem, geometry


def transfer(u_source, V_target, extend=False):
    """u_source (P1 on one mesh) as a Function on V_target (P1 on another mesh of the same domain).
    A target point outside the source mesh is an error, or with `extend` (curved boundaries of a
    non-nested family: an initial guess, not a measurement) takes the affine extension of u_source
    from its closest cell."""
    comm = V_target.mesh.comm
    n = kuhn_grid(u_source.function_space.mesh)
    moved = kuhn_transfer(u_source, n, V_target) if n else None
    if moved is not None:
        return moved
    index_map = V_target.dofmap.index_map
    n_owned = index_map.size_local
    points = V_target.tabulate_dof_coordinates()[:n_owned]
    counts = comm.allgather(n_owned)
    all_points = np.vstack(comm.allgather(points)) if sum(counts) else np.zeros((0, 3))
    values, found = evaluate(u_source, all_points)
    owner = np.where(found, comm.rank, comm.size).astype(np.int32)
    comm.Allreduce(MPI.IN_PLACE, owner, op=MPI.MIN)
    if np.any(owner == comm.size) and extend:
        values, owner = extend_outside(u_source, all_points, values, owner)
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
    first, end = colliding.offsets[:-1], colliding.offsets[1:]
    found = end > first  # each point's first colliding cell, if any
    cells = np.full(len(points), -1, dtype=np.int32)
    cells[found] = colliding.array[first[found]]
    values = np.zeros(len(points))
    if np.any(found):
        values[found] = u.eval(points[found], cells[found])[:, 0]
    return values, found


def extend_outside(u, points, values, owner):
    """(values, owner) completed at the points no rank's cell contains (owner == size): the affine
    extension of u from the closest cell over all ranks (the lowest rank on ties)."""
    msh = u.function_space.mesh
    comm = msh.comm
    missing = np.flatnonzero(owner == comm.size)
    cells, distance = closest_cells(msh, points[missing])
    nearest = distance.copy()
    comm.Allreduce(MPI.IN_PLACE, nearest, op=MPI.MIN)
    rank = np.where(distance == nearest, comm.rank, comm.size).astype(np.int32)
    comm.Allreduce(MPI.IN_PLACE, rank, op=MPI.MIN)
    mine = rank == comm.rank
    if np.any(mine):  # P1 on an affine cell: eval pulls the point back through the cell's affine map
        values[missing[mine]] = u.eval(points[missing[mine]], cells[mine])[:, 0]
    owner = owner.copy()
    owner[missing] = rank
    return values, owner


def closest_cells(msh, points):
    """(cells, squared distances): for each point the closest cell owned by this rank (inf if none)."""
    tdim = msh.topology.dim
    owned = np.arange(msh.topology.index_map(tdim).size_local, dtype=np.int32)
    if not len(owned) or not len(points):
        return np.zeros(len(points), dtype=np.int32), np.full(len(points), np.inf)
    tree = geometry.BoundingBoxTree(msh, tdim, owned)
    midpoints = geometry.create_midpoint_tree(msh, tdim, owned)
    cells = np.asarray(geometry.compute_closest_entity(tree, midpoints, msh, points), dtype=np.int32)
    return cells, np.asarray(geometry.squared_distance(msh, tdim, cells, points), dtype=float)


# --- the fast path: sources on a Kuhn grid ---------------------------------------------------------

def kuhn_grid(msh):
    """n when msh is the Kuhn triangulation of [0, 1]^d with n cells per side (every simplex a chain
    of unit steps from a grid point, as create_unit_square's 'right' diagonal and create_unit_cube
    make it), else 0; the same answer on every rank."""
    tdim, gdim = msh.topology.dim, msh.geometry.dim
    n_cells = msh.comm.allreduce(msh.topology.index_map(tdim).size_local, op=MPI.SUM)
    n = round((n_cells / (2 if tdim == 2 else 6)) ** (1 / tdim))
    local = msh.topology.index_map(tdim).size_local
    cells = msh.geometry.dofmap.array.reshape(-1, tdim + 1)[:local]
    x = msh.geometry.x[:, :tdim] * n
    grid = np.rint(x)
    ok = tdim == gdim and n > 0 and n_cells == (2 if tdim == 2 else 6) * n**tdim and np.allclose(x, grid, atol=1e-8)
    if ok and len(cells):
        vertices = grid[cells]  # (cells, d+1, d), ordered below by coordinate sum
        chain = np.take_along_axis(vertices, np.argsort(vertices.sum(axis=2), axis=1)[:, :, None], axis=1)
        steps = np.diff(chain, axis=1)  # a Kuhn simplex steps by one unit vector at a time
        ok = bool(np.all((steps == 0) | (steps == 1)) and np.all(steps.sum(axis=2) == 1))
    return n if msh.comm.allreduce(ok, op=MPI.LAND) else 0


def kuhn_transfer(u_source, n, V_target):
    """u_source (P1 on the Kuhn grid with n cells per side) at V_target's dofs, owned and ghost; None
    when a target dof lies outside [0, 1]^d, the grid's domain (on any rank)."""
    comm, tdim = V_target.mesh.comm, V_target.mesh.topology.dim
    targets = V_target.tabulate_dof_coordinates()[:, :tdim]
    if not comm.allreduce(bool(np.all((targets > -1e-12) & (targets < 1 + 1e-12))), op=MPI.LAND):
        return None
    V = u_source.function_space
    owned = V.dofmap.index_map.size_local
    points = np.rint(V.tabulate_dof_coordinates()[:owned, :tdim] * n).astype(np.int64)
    index = points @ (n + 1) ** np.arange(tdim)
    grid = np.zeros((n + 1) ** tdim)
    for where, values in zip(comm.allgather(index), comm.allgather(u_source.x.array[:owned])):
        grid[where] = values
    u_target = fem.Function(V_target)
    u_target.x.array[:] = kuhn_interpolate(grid, n, targets)
    return u_target


def kuhn_interpolate(grid, n, points):
    """The P1 interpolant of grid values on the Kuhn triangulation at `points` in [0, 1]^d: in the cube
    of corner c, with local coordinates t sorted as t_s1 >= ... >= t_sd, the simplex is the chain
    c, c + e_s1, c + e_s1 + e_s2, ... and the barycentric weights are 1 - t_s1, t_s1 - t_s2, ..., t_sd."""
    d = points.shape[1]
    scaled = np.clip(points * n, 0, n)
    corner = np.minimum(np.floor(scaled), n - 1).astype(np.int64)
    t = scaled - corner
    order = np.argsort(-t, axis=1)
    t_sorted = np.take_along_axis(t, order, axis=1)
    weights = -np.diff(np.hstack([np.ones((len(t), 1)), t_sorted, np.zeros((len(t), 1))]), axis=1)
    strides = (n + 1) ** np.arange(d)
    vertex = corner @ strides
    value = weights[:, 0] * grid[vertex]
    for k in range(d):
        vertex = vertex + strides[order[:, k]]
        value += weights[:, k + 1] * grid[vertex]
    return value
