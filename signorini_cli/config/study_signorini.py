"""The Signorini study's config (study_type: signorini): the variational inequality (paper eq. (8)) on
every level, no ε and no α."""

NAME = "signorini"
DOC = ""  # how the reference and `signorini init` describe it beside its name
POINTS = False
VI = True  # solves the problem's Signorini VI, whose nodal bounds u_i <= 0 are P1 only
LIMIT_ERROR = False
GEOMETRY = False
FIELDS = False
DEGREES = (1,)
UNUSED = {"alpha": "", "epsilon": "", "positive_part": "", "contact_quadrature": ""}
LIMIT = None
SECTION = None


def check_config(cfg, raw):
    """Rules across sections: none beyond the generic ones."""
    return cfg
