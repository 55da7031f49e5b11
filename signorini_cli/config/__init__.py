"""The study config: YAML read, checked and resolved into frozen dataclasses (`settings`), with the
expression language (`expressions`), PETSc options (`petsc_options`), mesh files and the column names."""
from .settings import (DEFAULT_DELTA, DOCS, LAWS, MAX_BYTES, MESH_KINDS,  # noqa: F401
                       Config, ConfigError, Continuation, Epsilon, Mesh, Output, PositivePart, Solver,
                       Verification, canonical, fingerprint, from_dict, key_paths, length, load, loads,
                       table_columns, template, to_dict, yaml_dump, yaml_load)
