"""How the generated pages write a rate and a flag in their tables."""


def rate(value):
    """A rate to two decimals, an en dash where there is none."""
    return "–" if value is None else f"{value:.2f}"


def yes(flag):
    return "yes" if flag else "no"
