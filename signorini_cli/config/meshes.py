"""The mesh section and Γ_C: built-in unit square/cube levels, gmsh geometries and .msh files with their
physical groups, the dimension and the contact boundary."""
import os
from pathlib import Path

from . import geometry_files
from . import validators as check
from .schema import DIAGONALS, FACES, GEOMETRY_KINDS, MESH_KINDS, REFINE, ConfigError, Mesh


def dimension(value, mesh):
    """2 or 3, the mesh's (the key defaults to it)."""
    dim = check.integer(value, "dimension")
    if dim not in (2, 3):
        raise ConfigError("dimension", f"must be 2 or 3, got {dim}")
    if mesh.dimension != dim:
        raise ConfigError("mesh.kind", f"{mesh.kind} is {mesh.dimension}-D but dimension is {dim}")
    return dim


def mesh(raw, path, folder):
    if isinstance(raw, dict) and raw.get("kind") in GEOMETRY_KINDS:
        return _geometry_mesh(raw, path, folder)
    check.keys(raw, path, required=("kind", "refinements"), optional=("diagonal",))
    s = check.Section(raw, path, Mesh)
    kind = s.choice("kind", tuple(MESH_KINDS) + GEOMETRY_KINDS)
    if kind != "unit_square" and "diagonal" in raw:
        raise ConfigError(s.at("diagonal"), f"only meaningful with kind: unit_square, not {kind}")
    levels = raw["refinements"]
    if not isinstance(levels, list) or not levels:
        raise ConfigError(s.at("refinements"), f"must be a non-empty list of cells per side, got {levels!r}")
    levels = tuple(check.integer(n, f"{path}.refinements[{i}]", low=1) for i, n in enumerate(levels))
    for i in range(1, len(levels)):
        if levels[i] <= levels[i - 1]:
            raise ConfigError(s.at("refinements"), f"must increase, got {list(levels)}")
    return Mesh(kind, levels, s.choice("diagonal", DIAGONALS))


def _geometry_mesh(raw, path, folder):
    """mesh: {kind: gmsh, geometry, sizes} or {kind: file, path}, optionally refine: uniform + refinements."""
    kind = raw["kind"]
    source, listed = ("geometry", "sizes") if kind == "gmsh" else ("path", "path")
    check.keys(raw, path, required=("kind", source, listed), optional=("refine", "refinements", "cache"))
    s = check.Section(raw, path, Mesh)
    refine = s.choice("refine", REFINE)
    if kind == "gmsh":
        given = s.string("geometry")
        geometry = _resolve(given, folder) if given.endswith(".geo") else given  # else a shipped name
        sources = (_geometry_file(geometry, s.at("geometry"), given),)
        entries = _sizes(raw["sizes"], s.at("sizes"))
    else:
        entries = _msh_files(raw["path"], s.at("path"), folder)
        sources, geometry = entries, ""
    if refine == "uniform":
        if len(entries) != 1:
            raise ConfigError(s.at(listed), f"refine: uniform refines one base mesh, got {len(entries)}")
        refinements = _refinements(raw.get("refinements"), s.at("refinements"))
    elif "refinements" in raw:
        raise ConfigError(s.at("refinements"), "only meaningful with refine: uniform")
    else:
        refinements = ()
    return Mesh(kind, refinements, geometry=geometry, sizes=entries if kind == "gmsh" else (),
                path=entries if kind == "file" else (), refine=refine,
                cache=_resolve(s.string("cache", empty=True), folder) if raw.get("cache") else "",
                groups=_groups(sources, s.at(source)), source_hash=geometry_files.source_hash(sources))


def _resolve(name, folder):
    """A path relative to `folder` (the config file's), normalised; absolute paths stay."""
    return os.path.normpath(folder / name)


def _geometry_file(name, path, given):
    geo = geometry_files.geometry_path(name)
    if not geo.is_file():
        shipped = ", ".join(geometry_files.shipped_geometries())
        raise ConfigError(path, f"{given!r} is neither a shipped geometry ({shipped}) nor an existing .geo file")
    return geo


def _msh_files(raw, path, folder):
    files = [raw] if isinstance(raw, str) else raw
    if not isinstance(files, list) or not files:
        raise ConfigError(path, f"must be a .msh file or a non-empty list of them, got {check.show(raw)}")
    for i, name in enumerate(files):
        where = path if isinstance(raw, str) else f"{path}[{i}]"
        if not isinstance(name, str) or not Path(folder / name).is_file():
            relative = " (relative to the config's folder)" if isinstance(name, str) and folder != Path(".") else ""
            raise ConfigError(where, f"no such mesh file: {name!r}{relative}")
    return tuple(_resolve(name, folder) for name in files)


def _sizes(raw, path):
    if not isinstance(raw, list) or not raw:
        raise ConfigError(path, f"must be a non-empty list of target cell sizes, got {check.show(raw)}")
    sizes = tuple(check.number(s, f"{path}[{i}]", positive=True) for i, s in enumerate(raw))
    if any(b >= a for a, b in zip(sizes, sizes[1:])):
        raise ConfigError(path, f"must decrease (finer levels last), got {list(sizes)}")
    return sizes


def _refinements(raw, path):
    if not isinstance(raw, list) or not raw:
        raise ConfigError(path, "must be a non-empty list of refinement counts (0 = the base mesh), got "
                                f"{check.show(raw)}")
    counts = tuple(check.integer(k, f"{path}[{i}]", low=0) for i, k in enumerate(raw))
    if any(b <= a for a, b in zip(counts, counts[1:])):
        raise ConfigError(path, f"must increase, got {list(counts)}")
    return counts


def _groups(sources, path):
    """The (name, dimension) physical groups every source defines, with a domain of dimension 2 or 3."""
    per_source = [geometry_files.physical_groups(s) for s in sources]
    groups = {name: dim for name, dim in per_source[0].items()
              if all(other.get(name) == dim for other in per_source[1:])}
    if not groups or max(groups.values()) not in (2, 3):
        raise ConfigError(path, f"{sources[0]} names no physical group of dimension 2 or 3 (the domain): "
                                "name the domain, Γ_C and Γ_D with Physical ... (\"name\")")
    return tuple(sorted(groups.items()))


def contact(value, mesh, dim):
    """A face name on the unit square/cube, or a physical group of dimension d - 1 of a gmsh/file mesh."""
    if mesh.kind in MESH_KINDS:
        return check.choice(value, "contact", FACES[dim])
    facet_groups = tuple(name for name, d in mesh.groups if d == dim - 1)
    if not facet_groups:
        raise ConfigError("contact", f"the mesh source has no physical group of dimension {dim - 1}")
    return check.choice(value, "contact", facet_groups)
