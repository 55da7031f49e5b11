"""The study types the config knows (study_type), one light module each: the registry's own list, and what a
problem's or a method's rules read of a study type (it solves the VI, ...) without importing the registry."""
from . import study_map, study_refinement, study_signorini, study_sweep, study_total

STUDY_TYPES = {unit.NAME: unit for unit in (study_refinement, study_signorini, study_sweep, study_total,
                                            study_map)}
