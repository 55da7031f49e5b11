"""The study types: each runs its levels and says what its record and report hold (no printing, no files)."""
from .level import Level  # noqa: F401
from .registry import STUDY_TYPES, of, run_study  # noqa: F401
