"""Validation of a whole config: YAML mapping -> frozen Config. The core sections are read by `sections` and
`meshes`; the chosen problem, method and study type (config/units.py) add their keys, sections and rules.
Every error names its key path."""
import contextlib
import dataclasses
import difflib
from pathlib import Path

from . import meshes, rendering, sections, units
from . import validators as check
from .schema import (GEOMETRY_KINDS, MAX_ALPHA_3D, REQUIRED, Config, ConfigError, Problem,
                     keys_of)


def validate(raw, folder=None):
    """Validate a raw mapping into a Config, a map's block left to config.map (loader.from_dict reads it);
    relative mesh paths are relative to `folder` (None: the working directory), and stored resolved."""
    with suggesting():
        cfg = _core(raw, folder)
        pde, method, study = units.chosen(cfg)
        cfg = dataclasses.replace(cfg, sections=_sections(raw, cfg))
        for key, hint in method.UNUSED.items():
            if key in raw:
                raise ConfigError(key, f"not used by problem.method {method.NAME}{hint}")
        cfg = method.check_config(pde.check_config(cfg, raw), raw)
        return _check_element(_study_type(_check_geometry_mesh(cfg, raw, study), raw, pde, study), pde, study)


def _core(raw, folder):
    """The core sections and the problem block."""
    check.keys(raw, "", required=REQUIRED, optional=keys_of(Config) + tuple(k for k, *_ in units.sections()))
    top = check.Section(raw, "", Config)
    study = top.string("study")
    if "/" in study or study in (".", "..") or not study.isprintable():  # no newline, NUL, tab ...
        raise ConfigError("study", f"must be a plain folder name, got {study!r}")
    if len(study.encode()) > 255:  # NAME_MAX of Linux file systems
        raise ConfigError("study", f"must be at most 255 bytes (a folder name), got {len(study.encode())}")
    mesh = meshes.mesh(raw["mesh"], "mesh", Path(folder or "."))
    dim = meshes.dimension(raw.get("dimension", mesh.dimension), mesh)
    alpha = top.number("alpha", low=1.0)
    outside = top.boolean("outside_theory")
    if dim == 3 and alpha > MAX_ALPHA_3D and not outside:
        raise ConfigError("alpha", f"must be <= 3 in 3-D (the paper's condition (5)), got {alpha:g} "
                                     "(outside_theory: true runs it, with no verdict)")
    epsilon = sections.epsilon(top.section("epsilon"), "epsilon")
    positive = sections.positive_part(top.section("positive_part"), "positive_part", epsilon)
    return Config(study=study, dimension=dim, alpha=alpha, epsilon=epsilon,
                  mesh=mesh, contact=meshes.contact(raw["contact"], mesh, dim),
                  problem=_problem(raw.get("problem"), "problem", dim), positive_part=positive,
                  contact_quadrature=sections.contact_quadrature(top.get("contact_quadrature"),
                                                                 "contact_quadrature", positive.kind),
                  solver=sections.solver(top.section("solver"), "solver"),
                  output=sections.output(top.section("output"), "output"),
                  verification=sections.verification(top.section("verification"), "verification",
                                                     raw.get("problem")),
                  expect=sections.expect(raw["expect"], "expect", raw.get("problem")) if "expect" in raw else None,
                  description=top.string("description", empty=True), outside_theory=outside,
                  element=sections.element(top.section("element"), "element"),
                  study_type=top.choice("study_type", tuple(units.STUDY_TYPES)))


def _problem(raw, path, dim):
    """The problem block, read by its PDE's module; the method chosen among those built for that PDE."""
    if raw is None:
        raise ConfigError(path, "missing: give problem.exact (manufactured) or problem.f")
    check.keys(raw, path, optional=keys_of(Problem))
    s = check.Section(raw, path, Problem)
    pde = units.PDES[s.choice("pde", tuple(units.PDES))]
    for name in raw:
        if name not in ("pde", "method") + pde.KEYS:
            takers = units.takers(units.PDES, lambda unit: name in unit.KEYS)
            raise ConfigError(s.at(name), f"only meaningful with problem.pde: {takers}")
    method = s.choice("method", tuple(units.METHODS))
    if pde.NAME not in units.METHODS[method].PDES:
        raise ConfigError(s.at("method"), f"{method} is not built for pde: {pde.NAME} "
                                          f"(it is for {', '.join(units.METHODS[method].PDES)})")
    return dataclasses.replace(pde.problem(raw, path, dim), method=method)


def _sections(raw, cfg):
    """The (key, section) pairs of the chosen units' own sections; a unit's section given to a config that
    did not choose it is refused."""
    chosen = units.chosen(cfg)
    pairs = []
    for kind, registered in units.KINDS.items():
        for name, unit in registered.items():
            if unit.SECTION is None:
                continue
            key = unit.SECTION.key
            if unit in chosen:
                pairs.append((key, unit.section(raw.get(key, {}), key)))
            elif key in raw and not any(u.SECTION is not None and u.SECTION.key == key for u in chosen):
                raise ConfigError(key, f"only meaningful with {kind}: {name}")
    return tuple(pairs)


def _check_geometry_mesh(cfg, raw, study):
    """gmsh/file meshes serve refinement studies; levels that gmsh meshes one by one are not nested (on a
    curved boundary not even the same polygon), but a reference solution or successive differences move
    each level onto a finer one."""
    v, mesh = cfg.verification, cfg.mesh
    if mesh.kind in GEOMETRY_KINDS and not study.GEOMETRY:
        raise ConfigError("mesh.kind", f"{mesh.kind} meshes serve refinement studies, not study_type "
                                       f"{cfg.study_type}")
    data_only = cfg.problem.exact is None
    diff = "diff" in (v.measures if v.measures is not None else ("diff",) if data_only else ())
    compared = diff or (data_only and v.reference_refinements > 0)
    if compared and mesh.kind in GEOMETRY_KINDS and mesh.refine == "none" and len(mesh.levels) > 1:
        raise ConfigError("mesh.refine", "levels meshed one by one are not nested, but a reference solution "
                                         "or successive differences compare levels on finer meshes: use "
                                         "refine: uniform (or verification.measures without diff and "
                                         "reference_refinements: 0)")
    return cfg


def _study_type(cfg, raw, pde, study):
    """The study type's rules: the blocks only some types read (map, limit), the keys it does not use, the
    Signorini problem of the types that solve the VI, its limit block."""
    for block, has in (("map", lambda unit: unit.POINTS), ("limit", lambda unit: unit.LIMIT is not None)):
        if block in raw and not has(study):
            raise ConfigError(block, f"only meaningful with study_type {units.takers(units.STUDY_TYPES, has)}")
    if study.POINTS:  # its block and points: config.map, which validates each point as a study
        return cfg
    if study.VI and not pde.VI:
        runs = units.takers(units.STUDY_TYPES, lambda unit: not unit.VI and not unit.POINTS)
        raise ConfigError("study_type", f"{study.NAME} solves the scalar Signorini problem; pde: {pde.NAME} "
                                        f"runs {runs} studies")
    for key, hint in study.UNUSED.items():
        if key in raw:
            raise ConfigError(key, f"not used by study_type {study.NAME}{hint}")
    if study.VI:
        pde.check_vi(cfg.problem, study)
    cfg = study.check_config(cfg, raw)
    if not study.FIELDS and cfg.output.fields:
        writers = units.takers(units.STUDY_TYPES, lambda unit: unit.FIELDS and not unit.POINTS)
        raise ConfigError("output.fields", f"not written by study_type {study.NAME} ({writers} only)")
    if study.LIMIT is None:
        return cfg
    return dataclasses.replace(cfg, limit=study.parse_limit(raw.get("limit"), "limit", cfg))


def _check_element(cfg, pde, study):
    """The element degree the problem and the study type have. What P2 supports: its contact term exact (each
    facet cut at the zeros of the quadratic trace) or by a Gauss rule (the vertex rule lumps P1), fields
    written only for P1 (XDMF stores the values at the mesh's vertices)."""
    degree = cfg.element.degree
    if degree not in pde.DEGREES:
        raise ConfigError("element.degree", f"{degree} is not an element of pde: {pde.NAME} (degrees "
                                            f"{', '.join(map(str, pde.DEGREES))})")
    if degree not in study.DEGREES:
        raise ConfigError("element.degree", f"{degree} is for study_type "
                                            f"{units.takers(units.STUDY_TYPES, lambda u: degree in u.DEGREES)}; "
                                            f"{study.NAME} solves the Signorini VI, whose nodal bounds u_i <= 0 "
                                            "are P1 only")
    if degree == 1:
        return cfg
    if cfg.output.fields:
        raise ConfigError("output.fields", "written for element.degree 1 only (XDMF stores vertex values)")
    if cfg.contact_quadrature == "vertex":
        raise ConfigError("contact_quadrature", "vertex lumps P1 only; with element.degree 2 use exact or a "
                                                "Gauss rule's degree (an integer)")
    return cfg


@contextlib.contextmanager
def suggesting():
    """Within: an unknown key's error says which key it probably means (knowing every registered section)."""
    try:
        yield
    except check.UnknownKey as err:
        close = suggest(str(err.name), err.section, err.allowed)
        hint = f" (did you mean {close!r}?)" if close else ""
        raise ConfigError(err.path, f"{err.message}{hint}") from None


def suggest(name, path, allowed):
    """The full dotted path of the key `name` probably means: a key of that name in another section (a
    top-level `exact` is `problem.exact`), else a close key of its own section, else of another."""
    paths = rendering.key_paths()
    elsewhere = [p for p in paths if p.rsplit(".", 1)[-1] == name]
    if elsewhere:
        return elsewhere[0]
    close = difflib.get_close_matches(name, allowed, n=1)
    if close:
        return check.join(path, close[0])
    by_name = {p.rsplit(".", 1)[-1]: p for p in reversed(paths)}  # the shallowest path per name
    close = difflib.get_close_matches(name, list(by_name), n=1, cutoff=0.8)  # stricter: a guess afar
    return by_name[close[0]] if close else None
