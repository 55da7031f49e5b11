"""The study types: each runs its levels and says what its record and report hold (no printing, no files)."""
from .level import Level  # noqa: F401
from .registry import STUDY_TYPES, Study, of, run, run_study, study_of  # noqa: F401
