"""The study config: YAML read (`loader`), checked and resolved into frozen dataclasses (`settings`), a rate
map's points (`map`), with the expression language (`expressions`), PETSc options (`petsc_options`), mesh
files and the column names."""
from .loader import from_dict, load, loads  # noqa: F401
from .settings import (DEFAULT_DELTA, DOCS, LAWS, MAX_BYTES, MESH_KINDS,  # noqa: F401
                       Config, ConfigError, Continuation, Epsilon, Mesh, Output, PositivePart, Solver,
                       Verification, canonical, fingerprint, key_paths, length, table_columns, template,
                       to_dict, yaml_dump, yaml_load)
