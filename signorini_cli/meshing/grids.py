"""The built-in grids of the unit square (diagonal right, left or crossed) and cube, built where they live.

Each rank makes the cells of its own slab of grid rows (2-D) or layers (3-D) and one block of the vertex
coordinates, both in the numbering and order of dolfinx 0.5.2's create_rectangle/create_box (so one rank
gets exactly the cells, vertices and order of create_unit_square/cube), and dolfinx.mesh.create_mesh
assembles the pieces; no rank ever holds the whole mesh and no graph partitioner runs.

Why every cut cell is also sent to its neighbour as a ghost: dolfinx 0.5.2 (mesh::create_topology,
vertex_ownerhip_groups) finds the vertices shared between ranks only through ghost cells. A vertex of an
owned cell that is also a vertex of a ghost cell is matched across ranks; every other vertex of an owned
cell is owned outright. A partition with no ghosts therefore owns each vertex on the cut twice (90 dofs
instead of 81 at N = 8). dolfinx's own partitioner always ghosts by facet and drops the ghosts afterwards
for GhostMode.none; the slab partitioner below does the same, in closed form."""
import numpy as np
import ufl

import dolfinx.graph
import dolfinx.mesh

# Corners of the unit square cell (v0, v1, v2, v3) = (x, x + e_x, x + e_y, x + e_x + e_y) and, crossed, its
# centre (4); of the unit cube v0..v7 = x + (bit 0) e_x + (bit 1) e_y + (bit 2) e_z. Per cell, dolfinx's order.
SQUARE_CELLS = {"right": [[0, 1, 3], [0, 2, 3]], "left": [[0, 1, 2], [1, 2, 3]],
                "crossed": [[0, 1, 4], [0, 2, 4], [1, 3, 4], [2, 3, 4]]}
CUBE_CELLS = [[0, 1, 3, 7], [0, 1, 7, 5], [0, 5, 7, 4], [0, 3, 2, 7], [0, 6, 4, 7], [0, 2, 6, 7]]


def create(comm, dim, n, diagonal="right", ghost_mode=dolfinx.mesh.GhostMode.shared_facet):
    """The unit square (dim 2, with `diagonal`) or cube (dim 3) with n cells per side, distributed."""
    rows = local_range(comm.rank, n, comm.size)
    cells, centre = grid_cells(dim, n, rows, diagonal)
    x = grid_vertices(dim, n, local_range(comm.rank, vertex_count(dim, n, centre), comm.size))
    dest = destinations(comm, dim, n, cells, rows)

    def partition(_comm, nparts, tdim, graph, _ghost_mode):
        assert nparts == comm.size and graph.num_nodes == len(cells)
        return dest
    cell = ufl.Cell("triangle" if dim == 2 else "tetrahedron", geometric_dimension=dim)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", cell, 1))
    return dolfinx.mesh.create_mesh(comm, cells, x, domain, ghost_mode=ghost_mode, partitioner=partition)


def local_range(rank, count, size):
    """[start, stop) of `rank`'s block of `count` items: dolfinx::MPI::local_range (the first
    count % size ranks take one more)."""
    base, extra = divmod(count, size)
    start = rank * base + min(rank, extra)
    return start, start + base + (rank < extra)


def row_owner(rows, count, size):
    """The rank whose local_range block of `count` rows holds each row (dolfinx::MPI::index_owner)."""
    base, extra = divmod(count, size)
    rows = np.asarray(rows)
    return np.where(rows < extra * (base + 1), rows // (base + 1),
                    extra + (rows - extra * (base + 1)) // max(base, 1))


def grid_cells(dim, n, rows, diagonal):
    """((cells, dim + 1) global vertex numbers of the cells in grid rows [rows) (2-D: rows of squares,
    3-D: layers of cubes), whether the grid has centre vertices (crossed)."""
    origin = np.arange(*rows, dtype=np.int64) * (n + 1) ** (dim - 1)  # v0 of each square/cube, x fastest
    for axis in reversed(range(dim - 1)):
        origin = (origin[:, None] + np.arange(n, dtype=np.int64) * (n + 1) ** axis).ravel()
    corners = origin[:, None] + np.array([sum(((k >> a) & 1) * (n + 1) ** a for a in range(dim))
                                          for k in range(2**dim)], dtype=np.int64)
    crossed = dim == 2 and diagonal == "crossed"
    if crossed:  # centres numbered after the (n + 1)^2 grid points, one per square in cell index order
        corners = np.hstack([corners, (n + 1) ** 2 + np.arange(rows[0] * n, rows[1] * n)[:, None]])
    local = np.array(SQUARE_CELLS[diagonal] if dim == 2 else CUBE_CELLS)
    return corners[:, local].reshape(-1, dim + 1), crossed


def vertex_count(dim, n, centre):
    """Number of vertices: the (n + 1)^d grid points and, crossed, the n^2 square centres."""
    return (n + 1) ** dim + (n**2 if centre else 0)


def grid_vertices(dim, n, block):
    """(vertices, dim) coordinates of the global vertices [block), as dolfinx computes them
    (x = 0 + (1/n) i, centres at (i + 1/2)/n), so that one rank's mesh is bit for bit create_unit_*'s."""
    v = np.arange(*block, dtype=np.int64)
    grid = v < (n + 1) ** dim
    index = np.stack([(v // (n + 1) ** a) % (n + 1) for a in range(dim)], axis=1).astype(float)
    if not grid.all():
        c = v[~grid] - (n + 1) ** 2
        index[~grid] = np.stack([c % n, c // n], axis=1) + 0.5
    return 0.0 + (1.0 / n) * index


def destinations(comm, dim, n, cells, rows):
    """The partition: each cell stays on this rank, and a cell with a facet on its slab's cut is ghosted
    to the rank across it (a facet on the plane of grid row k has dim vertices in that row of points)."""
    ghosts = np.full((len(cells), 2), -1, dtype=np.int32)
    per_row = len(cells) // max(rows[1] - rows[0], 1)
    for side, row, part in ((0, rows[0], slice(0, per_row)), (1, rows[1] - 1, slice(len(cells) - per_row, None))):
        across = row + (1 if side else -1)
        if rows[1] > rows[0] and 0 <= across < n and row_owner(across, n, comm.size) != comm.rank:
            plane = row + side  # the slab's bottom (row) or top (row + 1) plane of grid points
            layer = np.where(cells[part] < (n + 1) ** dim, cells[part] // (n + 1) ** (dim - 1), -1)
            cut = (layer == plane).sum(axis=1) == dim  # centres (crossed) lie on no plane
            ghosts[part, side] = np.where(cut, row_owner(across, n, comm.size), -1)
    keep = ghosts >= 0
    offsets = np.arange(len(cells) + 1, dtype=np.int32)
    offsets[1:] += np.cumsum(keep.sum(axis=1), dtype=np.int32)
    dest = np.column_stack([np.full(len(cells), comm.rank, dtype=np.int32), ghosts])
    return dolfinx.graph.create_adjacencylist(dest[np.column_stack([np.ones(len(cells), bool), keep])], offsets)
