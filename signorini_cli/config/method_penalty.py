"""The penalty method's config (problem.method: penalty): the compliance model of the paper, eq. (10), with
its keys at the top level (alpha, epsilon, positive_part, contact_quadrature); no section of its own."""

NAME = "penalty"
DOC = "the compliance model, ε and α"  # how the reference and `signorini init` describe it beside its name
PDES = ("poisson", "elasticity")  # the problems it is built for
SECTION = None  # no section of its own
UNUSED = {}  # top-level keys it refuses (key -> hint): the penalty method reads them all


def check_config(cfg, raw):
    """Rules across sections: none beyond the top-level keys it reads."""
    return cfg
