"""The refinement study's config (study_type: refinement): one solve per level; every core key applies."""

NAME = "refinement"
DOC = ""  # how the reference and `signorini init` describe it beside its name
POINTS = False  # not a map of studies
VI = False  # solves the problem itself, not its Signorini limit
LIMIT_ERROR = False
GEOMETRY = True  # runs on gmsh and .msh meshes
FIELDS = True  # writes output.fields
DEGREES = (1, 2)  # the element degrees it runs
UNUSED = {}  # top-level keys it does not use: key -> hint
LIMIT = None  # no limit block
SECTION = None


def check_config(cfg, raw):
    """Rules across sections: none beyond the generic ones."""
    return cfg
