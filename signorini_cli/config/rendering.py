"""A config as text and data: the commented template (`signorini init`) and the reference's rows, every key's
path (did-you-mean), the resolved config as plain YAML data (to_dict) and the hash that names its numbers."""
import dataclasses
import hashlib
import json

import yaml

from . import expressions, units
from .schema import DOCS, MESH_KINDS, POWER_LAW, SECTIONS, Config, fields_of, keys_of


def _entries(cls):
    """(name, section class or None, default, example, doc, only, required) of each key of a section, the
    sections the units register after the core keys of Config; a required key's doc starts with "required"."""
    rows = []
    for name in keys_of(cls):
        f = fields_of(cls)[name]
        required = f.metadata["required"]
        doc = f.metadata["doc"]
        if "{choices}" in doc:
            doc = doc.replace("{choices}", _choices(name if cls is Config else f"{cls.__name__.lower()}.{name}"))
        rows.append((name, f.type if f.type in SECTIONS else None, f.default, f.metadata["example"],
                     ("required; " if required else "") + doc, f.metadata["only"], required))
    if cls is Config:
        rows += [(name, section.cls, None, None, section.doc, only, False) for name, section, only in units.sections()]
    return rows


def _choices(path):
    """The units the key at `path` (study_type, problem.pde, problem.method) chooses among, each with its DOC:
    "poisson (the scalar model) | elasticity (docs/elasticity.md)"."""
    return " | ".join(name + (f" ({unit.DOC})" if unit.DOC else "") for name, unit in units.KINDS[path].items())


def template():
    """A commented config with every key and its default, generated from the dataclasses (so it lists
    exactly what the loader reads). Valid as it stands; a commented key applies only where it says."""
    head = [f"# signorini config: every key with its default (described in {DOCS}).",
            "# Required keys show an example; commented keys apply only where their comment says."]
    return "\n".join(head + _template_lines(Config, 0, False)) + "\n"


def _template_lines(cls, depth, commented):
    lines = []
    for name, section, value, example, doc, only, _ in _entries(cls):
        off = commented or bool(only)
        lead = ("# " if off else "") + "  " * depth  # a commented block uncomments as a whole
        comment = f"  # {doc}" + (f"; {only}" if only else "")
        if section is not None:
            lines.append(f"{lead}{name}:".ljust(40) + comment)
            lines += _template_lines(section, depth + 1, off)
            continue
        lines.append(f"{lead}{name}: {_flow(example if example is not None else value)}".ljust(40) + comment)
    return lines


def documented_keys(cls=Config, prefix=""):
    """(dotted path, default as YAML ("" for a section or a required key), description, when it applies) of
    every key, sections included: the config reference (docs/reference/config.md) is generated from these, as
    `signorini init` is; a required key's description starts with "required"."""
    rows = []
    for name, section, value, example, doc, only, required in _entries(cls):
        path = f"{prefix}.{name}" if prefix else name
        if section is not None:
            rows.append((path, "", doc, only))
            rows += documented_keys(section, path)
        else:
            shown = {} if value == () and isinstance(example, dict) else value  # a mapping kept as pairs
            rows.append((path, "" if required or value is None else _flow(shown), doc, only))
    return rows


def key_paths(cls=Config, prefix=""):
    """Every config key's dotted path, sections included."""
    return [path for path, *_ in documented_keys(cls, prefix)]


def _flow(value):
    """value as one line of YAML."""
    value = list(value) if isinstance(value, tuple) else value
    text = yaml.safe_dump(value, default_flow_style=True, width=1000, allow_unicode=True, sort_keys=False)
    return text.removesuffix("\n").removesuffix("\n...").strip()


# --- resolved settings ----------------------------------------------------------------------------

def to_dict(cfg):
    """The resolved config as plain YAML data, every default filled in; `loader.from_dict` reads it back.
    Keys a config's problem, method or study type refuses are left out."""
    out = _plain(cfg)
    out.pop("text", None)
    out["mesh"] = _mesh_dict(cfg.mesh)
    out = {"study": out.pop("study"), "description": out.pop("description"), **out}
    if cfg.epsilon.law != POWER_LAW:
        out["epsilon"].pop("exponent")  # only meaningful with law: power (rejected otherwise)
    if cfg.problem.exact is not None:  # the reference keys are for data-only scenes (rejected otherwise)
        for key in ("reference_refinements", "reference_epsilon"):
            out["verification"].pop(key)
    if cfg.expect is not None:
        out["expect"]["rates"] = dict(cfg.expect.rates)
    out["problem"]["define"] = {name: e.text for name, e in cfg.problem.define}
    if not cfg.problem.define:
        out["problem"].pop("define")
    if cfg.solver.method != "newtonls":  # the line search is for newtonls only (rejected otherwise)
        out["solver"].pop("line_search")
    pde, method, study = units.chosen(cfg)
    out["problem"] = {key: value for key, value in out["problem"].items() if key in ("pde", "method") + pde.KEYS}
    for key in (*method.UNUSED, *study.UNUSED):
        out.pop(key, None)
    if cfg.limit is not None:
        out["limit"] = {key: value for key, value in out["limit"].items()
                        if key in ("alpha", "fit_last") + study.LIMIT[0] + study.LIMIT[1]}
    return out


NOT_HASHED = ("text", "output", "description")  # where results go and comments do not change them


def canonical(cfg):
    """The validated settings that determine a study's numbers, as plain JSON-able data."""
    return {name: value for name, value in _plain(cfg, hashing=True).items() if name not in NOT_HASHED}


def fingerprint(cfg):
    """sha256 of canonical(cfg): equal for configs that compute the same study."""
    return hashlib.sha256(json.dumps(canonical(cfg), sort_keys=True, default=str).encode()).hexdigest()


def _mesh_dict(mesh):
    """The mesh keys its kind accepts (groups are read from the source, not given)."""
    if mesh.kind in MESH_KINDS:
        out = {"kind": mesh.kind, "refinements": list(mesh.refinements)}
        return dict(out, diagonal=mesh.diagonal) if mesh.kind == "unit_square" else out
    out = {"kind": mesh.kind}
    out.update({"geometry": mesh.geometry, "sizes": list(mesh.sizes)} if mesh.kind == "gmsh" else
               {"path": list(mesh.path)})
    if mesh.refine == "uniform":
        out.update(refine=mesh.refine, refinements=list(mesh.refinements))
    out["cache"] = mesh.cache
    return out


def _kept(f, item, hashing):
    """Whether field f with value item is written: not unset, not derived from other keys (a map's
    resolved points), and for the hash not a key hashed only when it differs from its default."""
    at_default = not f.metadata.get("hashed_at_default", True) and item == f.default
    return item is not None and not f.metadata.get("derived") and not (hashing and at_default)


def _plain(value, hashing=False):
    if isinstance(value, expressions.Expression):
        return value.text
    if dataclasses.is_dataclass(value):
        out = {}
        for f in dataclasses.fields(value):
            item = getattr(value, f.name)
            if f.name == "sections":  # the registered sections, each under its own key
                out.update((key, _plain(section, hashing)) for key, section in item)
            elif _kept(f, item, hashing):
                out[f.name] = dict(item) if f.name == "petsc_options" else _plain(item, hashing)  # (name, value)
        return out
    if isinstance(value, tuple):
        return [_plain(v, hashing) for v in value]
    return value
