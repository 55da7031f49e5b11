"""The study types: each runs its levels and returns the solves (no printing, no files)."""
from .level import Level  # noqa: F401
from .registry import STUDY_TYPES, run_study  # noqa: F401
