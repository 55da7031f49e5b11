"""The checks a study passes before its first solve, the same for a single study and for every point of a
map: the finest level fits in memory, PETSc takes the user's options on a small system, the contact rule
integrates alpha, gmsh meshes the geometry (and for a map's points their data on the coarsest level). What
they refuse is bad input (ConfigError), found before any file is written."""
from ..config import map as map_config
from ..meshing import geometries, meshes
from ..problems import contact, registry
from ..solve import preflight
from . import resources


def before_solving(cfg, comm, memory=True, copies=1):
    """ConfigError (on every rank) when cfg cannot be solved; `copies` groups of ranks may each hold
    one of its levels at once (a map's)."""
    for _, check in checks(memory, copies):
        check(cfg, comm)


def map_points(cfg, chosen, comm, memory=True, copies=1):
    """before_solving for each chosen point of a map, each check once per distinct input it reads, and the
    point's data on its coarsest level as its first level checks them (a single study refuses them there,
    before any file is kept); the ConfigError names the point (and the varied key at fault)."""
    with registry.checked_once(), meshes.kept():
        for reads, check in checks(memory, copies) + [(_posed, _data)]:
            seen = set()
            for k in chosen:
                point = cfg.map.studies[k]
                if repr(reads(point)) not in seen:
                    seen.add(repr(reads(point)))
                    try:
                        check(point, comm)
                    except map_config.ConfigError as err:
                        raise at_point(cfg, k, err) from None


def checks(memory=True, copies=1):
    """[(what a check reads of a config, the check(cfg, comm))]."""
    def fits(cfg, comm):
        resources.check_memory(cfg, comm, copies)
    listed = [(_sizes, fits)] if memory else []
    return listed + [(_solver, _options), (_contact, lambda cfg, comm: contact.check_alpha(cfg)),
                     (lambda cfg: cfg.mesh, _meshes)]


def _sizes(cfg):
    return cfg.mesh, cfg.element, cfg.problem, getattr(cfg, "verification", None)


def _solver(cfg):
    return cfg.solver, cfg.dimension


def _options(cfg, comm):
    preflight.check_options(cfg.solver, cfg.dimension, comm)


def _contact(cfg):
    return cfg.contact_quadrature, cfg.alpha, getattr(cfg, "limit", None)


def _posed(cfg):
    return cfg.mesh, cfg.contact, cfg.problem, cfg.epsilon, getattr(cfg, "material", None)


def _data(cfg, comm):
    """The data of cfg's coarsest level checked as its solve checks them (problems/posed.py)."""
    domain = meshes.build(cfg.mesh, cfg.contact, cfg.mesh.levels[0], comm)
    registry.check_posed(cfg, domain, None, cfg.epsilon(domain.h))


def _meshes(cfg, comm):
    """What gmsh cannot mesh is bad input, found before any level runs."""
    if cfg.mesh.kind == "gmsh":
        list(geometries.mesh_levels(cfg, comm))


def at_point(cfg, k, err):
    """err as it concerns map point k: under the grid's (or the explicit point's) key when it is a varied
    one, with the point's number and values."""
    values = cfg.map.values[k]
    key = next((key for key in values if err.path.startswith(key)), None)
    grid_points = len(cfg.map.values) - len(cfg.map.points)
    where = "map.grid" if k < grid_points else f"map.points[{k - grid_points}]"
    said = f"point {k} ({map_config.describe(values)})"
    if key is None:
        return map_config.ConfigError(err.path, f"{said}: {err.message}")
    return map_config.ConfigError(f"{where}.{key}", f"{said}: {err}")
