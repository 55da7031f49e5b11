"""Resource limits: the memory the finest level needs, estimated before any mesh is built, for every
mesh kind: built-in grids from N in closed form, gmsh geometries from their measure and the target size
(or the cached mesh's node count), .msh files from the node count in their header; times 4^r (2-D) or
8^r (3-D) for r uniform refinements."""
import os
from pathlib import Path

from mpi4py import MPI

from ..config import ConfigError, geometry_files, units
from ..meshing import geometries

# Peak memory (ru_maxrss) of one serial level on this machine, minus the 94 MB after the imports:
# 2-D N=256, 512 (MUMPS LU) 1690, 1740 bytes per dof; 3-D N=32, 48 (CG + BoomerAMG) 2710, 2580.
# With 7 (2-D) and 15 (3-D) Jacobian nonzeros per row, BYTES_PER_DOF + BYTES_PER_NONZERO * nnz/dof
# (1770 in 2-D, 2650 in 3-D) is within 5 % of every one.
BYTES_PER_DOF = 1000
BYTES_PER_NONZERO = 110
BYTES_PER_RANK = 100 * 2**20  # Python, dolfinx, PETSc and MPI loaded, before any mesh
# Unstructured P1 meshes: ~6 neighbours per vertex in 2-D, ~14 in 3-D (Euler: E ≈ 3V, E ≈ 7V).
ROW_NONZEROS = {2: 7, 3: 15}
# gmsh vertices per |Ω| / size^d (Mesh.MeshSizeMax = size): 2/sqrt(3) = 1.155 for equilateral triangles,
# measured 1.21, 1.20 at size 0.02 (unit square, half disk); in 3-D measured 0.92, 0.88 at size 0.05 (unit
# cube, half ball), falling with the size. The boundary adds more on coarse meshes, which fit anyway.
GMSH_DOFS_PER_MEASURE = {2: 1.15, 3: 0.85}
# P2 (element.degree 2): a dof per vertex and per edge. 2-D: E ≈ 3V, so 4 dofs per P1 dof; on the Kuhn grid
# a vertex dof couples with 19 dofs and an edge dof with 9, (19 + 3·9)/4 = 11.5 nonzeros per row. 3-D:
# E ≈ 7V, so 8 dofs per P1 dof; the unit cube's P2 stiffness has 25.8, 26.7, 27.2 nonzeros per row at
# N = 8, 12, 16, falling like 1/N to 28.6 (the boundary's rows are shorter). The bytes per dof and per
# nonzero are P1's fit above, not measured for P2.
P2_DOFS_PER_P1_DOF = {2: 4, 3: 8}
P2_ROW_NONZEROS = {2: 11.5, 3: 28.6}
# A vector problem (elasticity) has d dofs per node, each row coupling with d times the scalar neighbours:
# d times the dofs, d² times the nonzeros of the scalar space of the same element.


def level_size(mesh_cfg, n):
    """(dofs, Jacobian nonzeros) of P1 on the built-in level with n cells per side; None for a mesh
    kind whose size needs estimate_size."""
    if mesh_cfg.kind == "unit_square":
        if mesh_cfg.diagonal == "crossed":  # cell centres are vertices too: 8 neighbours at corners, 4 at centres
            return (n + 1)**2 + n**2, 9 * (n + 1)**2 + 5 * n**2
        return (n + 1)**2, 7 * (n + 1)**2  # 6 neighbours per interior vertex
    if mesh_cfg.kind == "unit_cube":
        return (n + 1)**3, 15 * (n + 1)**3  # 6 tetrahedra per cube: 14 neighbours per interior vertex
    return None


def needed_bytes(dofs, nonzeros, ranks):
    """Estimated peak memory of a level over all ranks (the fit above)."""
    return ranks * BYTES_PER_RANK + dofs * BYTES_PER_DOF + nonzeros * BYTES_PER_NONZERO


def check_memory(cfg, comm, copies=1):
    """ConfigError (naming the key of the levels) on every rank when the finest level, with its reference
    solution for a data-only scene, would need more memory than the nodes of `comm` have available; `copies`
    groups of its ranks may each hold such a level at once (a map's points). --ignore-memory-check skips it."""
    peak = peak_meshes(cfg, comm)
    if peak is None:
        return
    dofs, nonzeros = sum(d for _, d, _ in peak), sum(z for _, _, z in peak)
    need, have = needed_bytes(copies * dofs, copies * nonzeros, comm.size), available_on_nodes(comm)
    if need > have:
        what = "the finest level" if len(peak) == 1 else "the finest level with its reference solution"
        meshes = " and ".join(label for label, _, _ in peak)
        what += f", {copies} at once (one per group of ranks)" if copies > 1 else ""
        raise ConfigError(f"mesh.{cfg.mesh.level_key}",
                          f"{what} ({meshes}: {dofs:,} dofs, {nonzeros:,} Jacobian nonzeros) needs about "
                          f"{_gb(need)} of memory, more than the {_gb(have)} available; use --ignore-memory-check "
                          "to run it anyway")


def peak_meshes(cfg, comm):
    """[(label, dofs, nonzeros)] of the meshes alive at the peak: the largest level, and for a data-only
    scene the reference mesh, verification.reference_refinements uniform refinements finer; None when
    a size cannot be told before meshing (a geometry gmsh cannot read: reported when it meshes)."""
    peak = p1_peak_meshes(cfg, comm)
    if peak is None:
        return None
    if cfg.element.degree == 2:
        per_dof, per_row = P2_DOFS_PER_P1_DOF[cfg.mesh.dimension], P2_ROW_NONZEROS[cfg.mesh.dimension]
        peak = [(label, per_dof * dofs, round(per_row * per_dof * dofs)) for label, dofs, _ in peak]
    d = cfg.mesh.dimension if units.PDES[cfg.problem.pde].VECTOR else 1
    return [(label, d * dofs, d * d * nonzeros) for label, dofs, nonzeros in peak]


def p1_peak_meshes(cfg, comm):
    """peak_meshes for P1 elements."""
    extra = reference_refinements(cfg)
    if cfg.mesh.kind in ("unit_square", "unit_cube"):
        finest = cfg.mesh.levels[-1]
        return [(f"N={n}", *level_size(cfg.mesh, n)) for n in [finest] + ([finest * 2**extra] if extra else [])]
    sources = level_sources(cfg.mesh)
    base = base_dofs(cfg.mesh, sorted({source for source, _ in sources}, key=str), comm)
    if base is None:
        return None
    grow = 2 ** cfg.mesh.dimension
    source, r = max(sources, key=lambda level: base[level[0]] * grow ** level[1])
    dofs = base[source]
    rows = ROW_NONZEROS[cfg.mesh.dimension]
    return [(source_label(source, k), dofs * grow**k, rows * dofs * grow**k)
            for k in [r] + ([r + extra] if extra else [])]


def reference_refinements(cfg):
    """The uniform refinements of the finest level that a data-only scene's reference solution lives on."""
    verification = getattr(cfg, "verification", None)
    if cfg.problem.exact is None and verification is not None:
        return verification.reference_refinements
    return 0


def level_sources(mesh_cfg):
    """(gmsh size or .msh path, uniform refinements of it) for every level of a gmsh/file family."""
    if mesh_cfg.refine == "uniform":
        return [((mesh_cfg.sizes or mesh_cfg.path)[0], r) for r in mesh_cfg.levels]
    return [(entry, 0) for entry in mesh_cfg.levels]


def base_dofs(mesh_cfg, sources, comm):
    """{source: P1 dofs} of the meshes of gmsh sizes (a cache entry's node count, else |Ω| / size^d times
    the vertex density) or of .msh paths (the node count each header declares); None if one is unknown."""
    if mesh_cfg.kind == "file":
        counts = {path: _node_count(Path(path)) for path in sources}
        return None if None in counts.values() else counts
    geo = geometry_files.geometry_path(mesh_cfg.geometry)
    if not geo.is_file():
        return None
    counts = {size: _node_count(geometry_files.cache_file(mesh_cfg.cache, geo, size)) for size in sources}
    if None in counts.values():
        try:
            measure = geometries.geometry_measure(geo, mesh_cfg.dimension, comm)
        except geometries.GeometryError:
            return None
        density = GMSH_DOFS_PER_MEASURE[mesh_cfg.dimension] * measure
        counts = {size: count or round(density / size**mesh_cfg.dimension) for size, count in counts.items()}
    return counts


def source_label(source, refinements):
    """'size 0.0001' or the .msh file's name, with ' refined r times' when r > 0."""
    label = f"size {source:g}" if isinstance(source, (int, float)) else Path(source).name
    return label + (f" refined {refinements} times" if refinements else "")


def _node_count(path):
    """The node count of a .msh file's header, None when there is no such (readable) file."""
    try:
        return geometry_files.msh_node_count(path) if path.is_file() else None
    except (OSError, ValueError):
        return None


def available_on_nodes(comm):
    """Available memory summed over the nodes `comm` runs on (read once per node, the same on all ranks)."""
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    mine = available_bytes() if node.rank == 0 else 0
    node.Free()
    return comm.allreduce(mine, op=MPI.SUM)


def available_bytes():
    """This machine's available memory (MemAvailable, else free pages), capped by a cgroup limit."""
    free = _meminfo("MemAvailable")
    if free is None:
        free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    room = _cgroup_room()
    return free if room is None else min(free, room)


def _meminfo(key):
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            name, _, value = line.partition(":")
            if name == key:
                return int(value.split()[0]) * 1024  # kB
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_room():
    """Limit minus usage of this process's cgroup (v2, else v1), or None without a limit."""
    v1 = "/sys/fs/cgroup/memory/memory."
    for limit, usage in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                         (v1 + "limit_in_bytes", v1 + "usage_in_bytes")):
        try:
            cap, used = Path(limit).read_text().strip(), Path(usage).read_text().strip()
        except OSError:
            continue
        if cap.isdigit() and used.isdigit() and int(cap) < 2**60:  # v1 writes ~2^63 for "no limit"
            return max(int(cap) - int(used), 0)
        return None
    return None


def _gb(nbytes):
    return f"{nbytes / 2**30:.1f} GiB"
