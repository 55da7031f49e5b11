"""The rate map's config (study_type: map, docs/maps.md): its own block `map` (config/map.py), whose points
are refinement studies, each validated as one."""

NAME = "map"
DOC = ""  # how the reference and `signorini init` describe it beside its name
POINTS = True  # its points are studies of their own: config/map.py reads its block
VI = False
LIMIT_ERROR = False
GEOMETRY = True
FIELDS = True
DEGREES = (1, 2)
UNUSED = {}
LIMIT = None
SECTION = None


def check_config(cfg, raw):
    """Rules across sections: each point's, checked when config/map.py validates it."""
    return cfg
