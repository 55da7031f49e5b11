"""The study config: YAML read (`loader`, `reading`), checked (`validators`, `sections`, `meshes`, `settings`)
into the frozen dataclasses of `schema`, with each problem, contact method and study type adding its own keys and
rules (`units`); written back as YAML and hashed (`rendering`); a rate map's points (`map`), the expression
language (`expressions`), PETSc options (`petsc_options`), mesh files and the column names."""
from .loader import from_dict, load, loads  # noqa: F401
from .reading import MAX_BYTES, yaml_dump, yaml_load  # noqa: F401
from .rendering import canonical, fingerprint, key_paths, template, to_dict  # noqa: F401
from .schema import (DEFAULT_DELTA, DOCS, LAWS, MESH_KINDS, Config, ConfigError, Continuation,  # noqa: F401
                     Epsilon, Mesh, Output, PositivePart, Solver, Verification)
from .sections import length, table_columns  # noqa: F401
