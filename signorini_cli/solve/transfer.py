"""Moving a P1 or P2 function between meshes of one family (0.5.2 cannot interpolate across meshes).

No rank ever holds a mesh-sized array of another rank's data. Each rank sends its owned target dof
points only to the ranks whose owned source cells' bounding box contains them; those evaluate the
source where their cells contain the points and send the values back, and the lowest such rank's value
wins. For nested meshes every target cell lies in a source cell on which the source is a polynomial of
the target's degree, so the transfer is exact for P1 and P2. Points no source cell contains (a curved
boundary) are an error, or with `extend` take the extension of the closest cell's polynomial: only those
few points go to every rank.
A P1 source on the built-in Kuhn grid of the unit square ('right' diagonal) or cube takes a fast path:
each rank receives the source's vertex values on the grid layers its target points need, and the P1
interpolant is evaluated in closed form (the same values, no search). The same path moves GridValues, a
P1 function on that grid given by its vertex values alone (a resumed study's stored u_h, its mesh not built)."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from dolfinx import fem, geometry

CHUNK = 2**16  # target points interpolated at once on the Kuhn path (152 MiB of temporaries at 1M in one go)
BOX_TOL = 1e-8  # relative padding of a rank's bounding box: its points on the box's faces count as inside


@dataclass(frozen=True)
class GridValues:
    """A P1 function on the Kuhn grid of [0, 1]^d with n cells per side, as the values (m, bs) at the grid
    points (m, 3) this rank holds (any split of the points between ranks)."""
    n: int
    points: np.ndarray
    values: np.ndarray

    def onto(self, V_target):
        """This function at V_target's dofs (P1 of the same block size on a mesh inside [0, 1]^d)."""
        if V_target.dofmap.index_map_bs == 1:
            return self.component(0, V_target)
        return by_component(V_target, self.component)

    def component(self, i, V_target):
        moved = grid_transfer(self.points, self.values[:, i], self.n, V_target)
        if moved is None:
            raise ValueError("transfer: target points lie outside [0, 1]^d, the grid's domain")
        return moved


def transfer(u_source, V_target, extend=False):
    """u_source (P1 or P2 on one mesh, or GridValues) as a Function on V_target (the same element on
    another mesh of the same domain).
    A target point outside the source mesh is an error, or with `extend` (curved boundaries of a
    non-nested family: an initial guess, not a measurement) takes the extension of u_source's polynomial
    on its closest cell."""
    if isinstance(u_source, GridValues):
        return u_source.onto(V_target)
    if V_target.dofmap.index_map_bs > 1:
        return by_component(V_target, lambda i, V_i: transfer(u_source.sub(i).collapse(), V_i, extend))
    n = kuhn_grid(u_source.function_space.mesh) if u_source.function_space.ufl_element().degree() == 1 else 0
    moved = kuhn_transfer(u_source, n, V_target) if n else None
    if moved is not None:
        return moved
    n_owned = V_target.dofmap.index_map.size_local
    points = V_target.tabulate_dof_coordinates()[:n_owned]
    values, found = evaluate_routed(u_source, points)
    missing = np.flatnonzero(~found)
    if extend:
        values[missing] = extend_everywhere(u_source, points[missing])
    else:
        refuse_outside(V_target.mesh.comm, points[missing])
    u_target = fem.Function(V_target)
    u_target.x.array[:n_owned] = values
    u_target.x.scatter_forward()
    return u_target


def by_component(V_target, moved):
    """A vector P1 function on V_target made one component at a time: moved(i, V_i), its component i as a
    Function on the collapsed scalar space V_i."""
    u_target = fem.Function(V_target)
    for i in range(V_target.dofmap.index_map_bs):
        V_i, dofs = V_target.sub(i).collapse()
        u_target.x.array[dofs] = moved(i, V_i).x.array
    return u_target


def evaluate_routed(u, points):
    """(values, found) of u at this rank's `points`, evaluated by the ranks whose owned cells' bounding
    box holds them (two alltoalls of local size); the lowest rank that finds a point gives its value."""
    comm = u.function_space.mesh.comm
    boxes = comm.allgather(owned_box(u.function_space.mesh))
    routes = [np.flatnonzero(((points >= lo) & (points <= hi)).all(axis=1)) for lo, hi in boxes]
    received = comm.alltoall([points[route] for route in routes])
    values, found = evaluate(u, np.vstack(received) if received else np.zeros((0, 3)))
    cuts = np.cumsum([len(p) for p in received])[:-1]
    answers = comm.alltoall(list(zip(np.split(values, cuts), np.split(found, cuts))))
    out, hit = np.zeros(len(points)), np.zeros(len(points), dtype=bool)
    for route, (vals, ok) in reversed(list(zip(routes, answers))):  # the lowest rank is written last
        out[route[ok]], hit[route[ok]] = vals[ok], True
    return out, hit


def owned_box(msh):
    """(lower, upper) corners of the bounding box of this rank's owned cells, padded by BOX_TOL of its
    size (empty: a box nothing is inside)."""
    tdim = msh.topology.dim
    owned = msh.topology.index_map(tdim).size_local
    x = msh.geometry.x[np.unique(msh.geometry.dofmap.array.reshape(-1, tdim + 1)[:owned])]
    if not len(x):
        return np.full(3, np.inf), np.full(3, -np.inf)
    lower, upper = x.min(axis=0), x.max(axis=0)
    pad = BOX_TOL * max(np.max(upper - lower), 1.0)
    return lower - pad, upper + pad


def refuse_outside(comm, outside):
    """ValueError on every rank when some rank has target points outside the source mesh."""
    counts = comm.allgather((len(outside), outside[0] if len(outside) else None))
    total = sum(count for count, _ in counts)
    if total:
        example = next(point for count, point in counts if count)
        raise ValueError(f"transfer: {total} target points lie outside the source mesh, e.g. {example}")


def extend_everywhere(u, points):
    """The affine extension of u at this rank's `points` (outside every source cell) from the closest
    cell over all ranks: these boundary points alone are gathered on every rank."""
    comm = u.function_space.mesh.comm
    counts = comm.allgather(len(points))
    if not sum(counts):
        return np.zeros(0)
    every = np.vstack(comm.allgather(points))
    values, owner = extend_outside(u, every, np.zeros(len(every)), np.full(len(every), comm.size, np.int32))
    values = np.where(owner == comm.rank, values, 0.0)
    comm.Allreduce(MPI.IN_PLACE, values, op=MPI.SUM)
    start = sum(counts[:comm.rank])
    return values[start:start + len(points)]


def evaluate(u, points):
    """(values, found): u at `points` where a cell owned by this rank contains them, else (0, False)."""
    msh = u.function_space.mesh
    tdim = msh.topology.dim
    n_cells = msh.topology.index_map(tdim).size_local
    if not len(points) or not n_cells:
        return np.zeros(len(points)), np.zeros(len(points), dtype=bool)
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
    V = u_source.function_space
    owned = V.dofmap.index_map.size_local
    return grid_transfer(V.tabulate_dof_coordinates()[:owned], u_source.x.array[:owned], n, V_target)


def grid_transfer(points, values, n, V_target):
    """The P1 function on the Kuhn grid with n cells per side whose values at the grid points (m, 3) held by
    this rank are `values` (m,), at V_target's dofs; None when a target dof lies outside [0, 1]^d (on any
    rank). Each rank receives the grid values on the layers (last axis) its targets need, from the ranks
    that hold them."""
    comm, tdim = V_target.mesh.comm, V_target.mesh.topology.dim
    targets = V_target.tabulate_dof_coordinates()[:, :tdim]
    if not comm.allreduce(bool(np.all((targets > -1e-12) & (targets < 1 + 1e-12))), op=MPI.LAND):
        return None
    points = np.rint(points[:, :tdim] * n).astype(np.int64)
    index, layer = points @ (n + 1) ** np.arange(tdim), (n + 1) ** (tdim - 1)
    wanted = comm.allgather(needed_layers(targets, n))
    sent = [(index[m], values[m]) for m in ((points[:, -1] >= lo) & (points[:, -1] <= hi) for lo, hi in wanted)]
    lo, hi = wanted[comm.rank]
    grid = np.zeros(max(hi - lo + 1, 0) * layer)
    for where, vals in comm.alltoall(sent):
        grid[where - lo * layer] = vals
    u_target = fem.Function(V_target)
    for start in range(0, len(targets), CHUNK):  # in chunks: a dozen temporaries per point, not per mesh
        u_target.x.array[start:start + CHUNK] = kuhn_interpolate(grid, n, targets[start:start + CHUNK], lo * layer)
    return u_target


def needed_layers(points, n):
    """(first, last) grid layer along the last axis that kuhn_interpolate reads at `points` ((0, -1): none)."""
    if not len(points):
        return 0, -1
    corner = np.minimum(np.floor(np.clip(points[:, -1] * n, 0, n)), n - 1).astype(np.int64)
    return int(corner.min()), int(corner.max()) + 1


def kuhn_interpolate(grid, n, points, offset=0):
    """The P1 interpolant of grid values on the Kuhn triangulation at `points` in [0, 1]^d (grid[k] is the
    value at grid point k + offset, numbered x fastest): in the cube
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
    vertex = corner @ strides - offset
    value = weights[:, 0] * grid[vertex]
    for k in range(d):
        vertex = vertex + strides[order[:, k]]
        value += weights[:, k + 1] * grid[vertex]
    return value
