"""Resource limits: the memory the finest level needs, estimated before any mesh is built."""
from pathlib import Path

from .config import ConfigError

# Peak memory (ru_maxrss) of one serial level on this machine, minus the 94 MB after the imports:
# 2-D N=256, 512 (MUMPS LU) 1690, 1740 bytes per dof; 3-D N=32, 48 (CG + BoomerAMG) 2710, 2580.
# With 7 (2-D) and 15 (3-D) Jacobian nonzeros per row, BYTES_PER_DOF + BYTES_PER_NONZERO * nnz/dof
# (1770 in 2-D, 2650 in 3-D) is within 5 % of every one.
BYTES_PER_DOF = 1000
BYTES_PER_NONZERO = 110
BYTES_PER_RANK = 100 * 2**20  # Python, dolfinx, PETSc and MPI loaded, before any mesh


def level_size(mesh_cfg, n):
    """(dofs, Jacobian nonzeros) of P1 on the level with n cells per side; None for a mesh kind
    whose size is not known before it is built."""
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


def check_memory(cfg, comm):
    """ConfigError on every rank when the finest level (with its reference solution, for a data-only
    scene) would need more memory than the nodes of `comm` have available. --force skips the check."""
    sizes = [level_size(cfg.mesh, n) for n in peak_levels(cfg)]
    if None in sizes:
        return
    dofs, nonzeros = sum(d for d, _ in sizes), sum(z for _, z in sizes)
    need, have = needed_bytes(dofs, nonzeros, comm.size), available_on_nodes(comm)
    if need > have:
        what = ("the finest level" if len(sizes) == 1 else "the finest level with its reference solution")
        cells = " and ".join(f"N={n}" for n in peak_levels(cfg))
        raise ConfigError("mesh.refinements", f"{what} ({cells}: {dofs:,} dofs, {nonzeros:,} Jacobian nonzeros) "
                                              f"needs about {_gb(need)} of memory, more than the {_gb(have)} "
                                              "available; use --force to run it anyway")


def peak_levels(cfg):
    """Cells per side of the meshes alive at the peak: the finest level, and for a data-only scene
    the reference solution's mesh, verification.reference_refinements times finer."""
    finest = cfg.mesh.levels[-1]  # gmsh/file levels: no size known before meshing
    verification = getattr(cfg, "verification", None)
    if cfg.problem.exact is None and verification is not None and verification.reference_refinements > 0:
        return [finest, finest * 2**verification.reference_refinements]
    return [finest]


def available_on_nodes(comm):
    """Available memory summed over the nodes `comm` runs on (read once per node, the same on all ranks)."""
    from mpi4py import MPI
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    mine = available_bytes() if node.rank == 0 else 0
    node.Free()
    return comm.allreduce(mine, op=MPI.SUM)


def available_bytes():
    """This machine's available memory (MemAvailable, else free pages), capped by a cgroup limit."""
    free = _meminfo("MemAvailable")
    if free is None:
        import os
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
