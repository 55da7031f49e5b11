"""Meshes from gmsh: a .geo geometry meshed on rank 0 into the .msh cache, or a user's .msh file, read
on rank 0 and distributed with dolfinx.io.gmshio.model_to_mesh. Physical groups, not coordinates,
decide Γ_C: the group the config's `contact` names; every other boundary facet is Γ_D."""
import dataclasses
import logging
import signal
import sys
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import cpp, fem

from .. import config
from ..config import ConfigError, geometry_files
from ..system import child, errors, files
from . import refinement
from .domain import CONTACT, domain_of, tag_facets

logger = logging.getLogger(__name__)


class GeometryError(RuntimeError):
    """gmsh could not mesh a geometry or read a mesh file (raised on every rank alike)."""


def build(mesh_cfg, contact, level, comm=MPI.COMM_WORLD):
    """One level: `level` is a gmsh size or a .msh path, or with refine: uniform the number of
    uniform refinements of the base mesh (nested levels). N is the number of cells."""
    if mesh_cfg.refine == "uniform":
        domain = read_level(mesh_cfg, contact, (mesh_cfg.sizes or mesh_cfg.path)[0], comm)
        for _ in range(level):
            domain = refinement.refine(domain)
        size = mesh_cfg.sizes[0] / 2**level if mesh_cfg.sizes else None
    else:
        domain = read_level(mesh_cfg, contact, level, comm)
        size = level if mesh_cfg.kind == "gmsh" else None
    return dataclasses.replace(domain, columns=level_columns(domain, size))


def read_level(mesh_cfg, contact, entry, comm=MPI.COMM_WORLD):
    """The mesh of a gmsh size (through the cache) or of a .msh path, with Γ_C and Γ_D tagged."""
    if mesh_cfg.kind == "gmsh":
        geo = geometry_files.geometry_path(mesh_cfg.geometry)
        path, _ = mesh_file(geo, entry, mesh_cfg.dimension, mesh_cfg.cache, comm)
    else:
        path = Path(entry)
    msh, facet_groups, groups = read_msh(path, mesh_cfg.dimension, comm)
    if contact not in groups:
        raise GeometryError(f"{path}: no physical group {contact!r} of dimension {mesh_cfg.dimension - 1} "
                            f"(it has: {', '.join(groups) or 'none'})")
    contact_facets = facet_groups.indices[facet_groups.values == groups[contact]]
    tags = tag_facets(msh, lambda boundary: np.isin(boundary, contact_facets))
    return domain_of(msh, tags, msh.topology.index_map(msh.topology.dim).size_global)


# --- gmsh on rank 0 ------------------------------------------------------------------------------

def mesh_file(geo, size, dim, cache_dir="", comm=MPI.COMM_WORLD):
    """(path, generated): the cached .msh of `geo` at `size` (in `cache_dir`, else where
    geometry_files.cache_folder says), meshed by gmsh on rank 0 on a miss."""
    def work():
        path = geometry_files.cache_file(cache_dir, geo, size)
        if path.exists():
            return path, False
        with files.folder_for(path.parent):  # gmsh failing on a garbage .geo leaves no empty cache folder
            files.replace(path, lambda tmp: child.in_child(generate, geo, size, dim, tmp))  # signals end it
        logger.info("meshed %s at size %g: %s", geo, size, path)
        return path, True
    return _on_rank0(comm, work, f"meshing {geo} at size {size:g}")


def generate(geo, size, dim, target):
    """Mesh the .geo file with gmsh at target cell size `size` and write it to `target` (.msh 4.1)."""
    gmsh = _import_gmsh()
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(geo))
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)  # one target size everywhere, not the
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)      # points' (or gmsh's default bbox/10)
        gmsh.option.setNumber("Mesh.Binary", 1)
        gmsh.model.mesh.generate(dim)
        gmsh.write(str(target))
    finally:
        _finalize(gmsh)


def geometry_measure(geo, dim, comm=MPI.COMM_WORLD):
    """|Ω| of a .geo geometry (area in 2-D, volume in 3-D), summed over a coarse gmsh mesh of it (cells a
    tenth of its bounding box's diameter) on rank 0: cheap, whatever the geometry's kernel."""
    def work():
        gmsh = _import_gmsh()
        gmsh.initialize()
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.open(str(geo))
            box = np.array(gmsh.model.getBoundingBox(-1, -1))
            gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
            gmsh.option.setNumber("Mesh.MeshSizeMax", np.linalg.norm(box[3:] - box[:3]) / 10)
            gmsh.model.mesh.generate(dim)
            return simplex_measure(gmsh, dim)
        finally:
            _finalize(gmsh)
    return _on_rank0(comm, work, f"measuring {geo}")


def simplex_measure(gmsh, dim):
    """Total area (dim 2) or volume (3) of the linear simplices of gmsh's current mesh."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    x = np.zeros((int(tags.max()) + 1 if len(tags) else 0, 3))
    x[tags.astype(np.int64)] = coords.reshape(-1, 3)
    total = 0.0
    for kind, _, nodes in zip(*gmsh.model.mesh.getElements(dim)):
        if kind not in (2, 4):  # 3-node triangles, 4-node tetrahedra
            continue
        cells = x[nodes.astype(np.int64).reshape(-1, dim + 1)]
        edges = cells[:, 1:] - cells[:, :1]
        if dim == 2:
            total += np.linalg.norm(np.cross(edges[:, 0], edges[:, 1]), axis=1).sum() / 2
        else:
            total += np.abs(np.linalg.det(edges)).sum() / 6
    return float(total)


def read_msh(path, gdim, comm=MPI.COMM_WORLD):
    """(mesh, facet tags with the physical group tags, {group name: tag} of dimension gdim - 1)."""
    gmsh = _import_gmsh()
    from dolfinx.io import gmshio

    def open_model():
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(path))
        gmsh.model.mesh.renumberNodes()  # model_to_mesh needs node tags 1..n without gaps
        return {gmsh.model.getPhysicalName(d, tag): tag for d, tag in gmsh.model.getPhysicalGroups(gdim - 1)}
    if comm.rank == 0:
        gmsh.initialize()
    try:
        groups = _on_rank0(comm, open_model, f"reading {path}")
        msh, _, facet_groups = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=gdim)
    finally:
        if comm.rank == 0:
            _finalize(gmsh)
    return msh, facet_groups, groups


def _import_gmsh():
    """gmsh, imported without letting it reset Ctrl-C to 'kill' (its module does so on import)."""
    handler = signal.getsignal(signal.SIGINT)
    import gmsh
    signal.signal(signal.SIGINT, handler)
    return gmsh


def _finalize(gmsh):
    """gmsh.finalize, keeping the SIGINT handler in place (finalize puts back the one gmsh found on import)."""
    handler = signal.getsignal(signal.SIGINT)
    gmsh.finalize()
    signal.signal(signal.SIGINT, handler)


def _on_rank0(comm, work, what):
    """work() on rank 0, its result on every rank; a failure is raised on every rank, none left waiting."""
    result, error = None, None
    if comm.rank == 0:
        try:
            result = work()
        except Exception as err:  # gmsh raises bare Exception; whatever it is, every rank must hear of it
            error = f"{what}: {err}"
    result, error = comm.bcast((result, error), root=0)
    if error is not None:
        raise GeometryError(error)
    return result


# --- per-level columns ---------------------------------------------------------------------------

def level_columns(domain, size=None):
    """The mesh's own figures for the table: the gmsh target size, h_min, |Γ_C| and the quasi-uniformity
    max h_F / min h_F of the trace mesh on Γ_C (the paper needs it bounded for d = 3 or α > 2)."""
    columns = {} if size is None else {"target_size": size}
    columns["h_min"] = domain.h_min
    columns["gamma_c_measure"] = contact_measure(domain)
    columns["gamma_c_quasi_uniformity"] = contact_quasi_uniformity(domain)
    return columns


def contact_measure(domain):
    """|Γ_C| of the discrete (polygonal/polyhedral) mesh: length in 2-D, area in 3-D."""
    msh = domain.mesh
    ds_c = ufl.Measure("ds", domain=msh, subdomain_data=domain.facet_tags)(CONTACT)
    one = fem.Constant(msh, 1.0)
    return msh.comm.allreduce(fem.assemble_scalar(fem.form(one * ds_c)), op=MPI.SUM)


def contact_quasi_uniformity(domain):
    """max h_F / min h_F over the facets F of Γ_C (h_F: the facet's diameter), over all ranks."""
    msh = domain.mesh
    facets = domain.facet_tags.indices[domain.facet_tags.values == CONTACT]
    h_f = cpp.mesh.h(msh._mesh, msh.topology.dim - 1, facets) if len(facets) else np.zeros(0)
    h_max = msh.comm.allreduce(h_f.max() if h_f.size else 0.0, op=MPI.MAX)
    h_min = msh.comm.allreduce(h_f.min() if h_f.size else np.inf, op=MPI.MIN)
    return h_max / h_min


# --- make meshes ---------------------------------------------------------------------------------

def mesh_levels(cfg, comm=MPI.COMM_WORLD):
    """Mesh a gmsh config's levels (the base mesh with refine: uniform) into its cache, yielding
    (cache file, generated) per mesh; what gmsh cannot mesh is a ConfigError naming mesh.geometry."""
    geo = geometry_files.geometry_path(cfg.mesh.geometry)
    for size in cfg.mesh.sizes:
        try:
            yield mesh_file(geo, size, cfg.dimension, cfg.mesh.cache, comm)
        except GeometryError as err:
            raise ConfigError("mesh.geometry", str(err)) from None


def cache_configs(paths, comm=MPI.COMM_WORLD):
    """mesh_levels of each gmsh config: yields (config path, cache file, generated). Other mesh kinds
    need nothing."""
    for path in paths:
        cfg = config.load(path)
        if cfg.mesh.kind == "gmsh":
            yield from ((path, *entry) for entry in mesh_levels(cfg, comm))


def main(argv=None):
    """`python -m signorini_cli.meshing.geometries CONFIG...` (make meshes): fill the mesh cache."""
    try:
        for path, msh, generated in cache_configs(sys.argv[1:] if argv is None else argv):
            print(f"{'meshed' if generated else 'cached'}  {msh}  ({path})")
    except (ConfigError, OSError) as err:
        errors.print_error("", err, program="signorini meshes")
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
