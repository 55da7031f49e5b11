"""The limit block of the ε → 0 studies (docs/limit.md): the α values and how many finest points a rate
fits; each study type adds its own keys (the ε of a sweep, the exponents of a total-error study)."""
from . import validators as check
from .schema import MAX_ALPHA_3D, ConfigError, Limit, default


def block(raw, path, kind, required, optional, dim, outside):
    """The block's keys checked, its Section, α and fit_last."""
    if raw is None:
        raise ConfigError(path, f"missing: study_type {kind} needs a limit block")
    check.keys(raw, path, required=required, optional=("alpha", "fit_last") + optional)
    s = check.Section(raw, path, Limit)
    alpha = check.numbers(raw.get("alpha", list(default(Limit, "alpha"))), s.at("alpha"), low=1.0)
    if dim == 3 and max(alpha) > MAX_ALPHA_3D and not outside:
        raise ConfigError(f"{path}.alpha", f"must be <= 3 in 3-D (the paper's condition (5)), got {max(alpha):g}")
    return s, alpha, s.integer("fit_last", low=2)
