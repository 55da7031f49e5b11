"""The sections every study has: the ε law, the positive part, the contact quadrature, the element, the solver
(with PETSc options), the output, verification and expect."""
import math

from . import expressions
from . import petsc_options as petsc
from . import validators as check
from .schema import (CONTACT_QUADRATURES, DEFAULT_DELTA, ERROR_NORMS, LAWS, LINE_SEARCHES, LINEAR_SOLVERS,
                     MAX_REFERENCE_REFINEMENTS, MEASURES, METHODS, ON_FAILURE, POSITIVE_PARTS, POWER_LAW,
                     PRECONDITIONERS, REFERENCE_EPSILONS, REFERENCE_NORMS, STRATEGIES, TABLE_COLUMNS, ConfigError,
                     Continuation, Element, Epsilon, Expect, Output, PositivePart, Solver, Verification, keys_of)


def epsilon(raw, path):
    check.keys(raw, path, optional=keys_of(Epsilon))
    s = check.Section(raw, path, Epsilon)
    law = s.choice("law", tuple(LAWS))
    if "exponent" in raw and law != POWER_LAW:
        raise ConfigError(s.at("exponent"), f"only meaningful with law: {POWER_LAW}, not {law}")
    return Epsilon(law, s.number("theta", positive=True), s.number("exponent"))


def positive_part(raw, path, epsilon):
    if isinstance(raw, str):
        raw = {"kind": raw}
    check.keys(raw, path, optional=keys_of(PositivePart))
    s = check.Section(raw, path, PositivePart)
    kind = s.choice("kind", POSITIVE_PARTS)
    if kind == "exact":
        if "delta" in raw:
            raise ConfigError(s.at("delta"), "only meaningful with kind: smooth")
        return PositivePart()
    delta = check.expression(raw.get("delta", DEFAULT_DELTA), s.at("delta"), ("h", "eps"))
    _check_delta(delta, s.at("delta"), epsilon)
    return PositivePart(kind, delta)


# where δ(h, eps) is checked: every h of a study lies in (0, 1] (the domains are unit-sized and meshes
# finer than 1e-6 do not fit in memory), and eps is the law's or that of an ε → 0 sweep
DELTA_H = tuple(10.0 ** -k for k in range(7))
DELTA_EPS = tuple(10.0 ** -k for k in range(0, 13, 2))


def _check_delta(delta, path, epsilon):
    """δ > 0 with δ² a positive finite number at every (h, eps) a study can meet: δ = 0 makes the
    smoothed [u]_+ non-differentiable (NaN), δ² = inf or 0 overflows or underflows."""
    for h, eps in _delta_points(epsilon):
        try:
            value = delta({"h": h, "eps": eps}, expressions.math_functions())
            ok = value > 0 and 0 < value * value < math.inf
        except (ValueError, OverflowError, ZeroDivisionError):
            value, ok = math.nan, False
        if not ok:
            raise ConfigError(path, f"must be > 0 with a finite, nonzero square for every h in (0, 1] and "
                                    f"eps > 0, got {value:g} at h = {h:g}, eps = {eps:g}")


def _delta_points(epsilon):
    """The (h, eps) where δ is checked: DELTA_H against DELTA_EPS and the law's own eps(h)."""
    for h in DELTA_H:
        try:
            own = (epsilon(h),)
        except OverflowError:  # power law with a large negative exponent: not an eps a level can have
            own = ()
        yield from ((h, eps) for eps in DELTA_EPS + own)


def contact_quadrature(value, path, positive_kind):
    """exact | vertex | a Gauss rule's degree >= 1; exact and vertex integrate the exact positive
    part (the smooth one keeps its UFL quadrature)."""
    if isinstance(value, int) and not isinstance(value, bool):
        return check.integer(value, path, low=1)
    if value not in CONTACT_QUADRATURES:
        raise ConfigError(path, f"{value!r} is not one of {', '.join(CONTACT_QUADRATURES)} "
                                "or an integer >= 1")
    if value == "vertex" and positive_kind != "exact":
        raise ConfigError(path, "vertex lumps the exact positive part; positive_part: smooth keeps its quadrature")
    return value


def element(raw, path):
    check.keys(raw, path, optional=keys_of(Element))
    return Element(degree=check.Section(raw, path, Element).integer("degree", low=1, high=2))


def solver(raw, path):
    check.keys(raw, path, optional=keys_of(Solver))
    s = check.Section(raw, path, Solver)
    method = s.choice("method", METHODS)
    if method == "newtontr" and "line_search" in raw:
        raise ConfigError(s.at("line_search"), "only meaningful with method: newtonls")
    return Solver(rtol=s.number("rtol", positive=True), atol=s.number("atol", positive=True),
                  max_it=s.integer("max_it", low=1), linear=s.choice("linear", LINEAR_SOLVERS),
                  line_search=s.choice("line_search", LINE_SEARCHES), on_failure=s.choice("on_failure", ON_FAILURE),
                  petsc_options=_petsc_options(raw.get("petsc_options") or {}, s.at("petsc_options")),
                  strategy=s.choice("strategy", STRATEGIES), method=method, stol=s.number("stol", low=0.0),
                  preconditioner=s.choice("preconditioner", PRECONDITIONERS),
                  linear_rtol=s.number("linear_rtol", positive=True), linear_fallback=s.boolean("linear_fallback"),
                  inexact=s.boolean("inexact"), continuation=_continuation(s.section("continuation"),
                                                                           s.at("continuation")),
                  condition_max_dofs=s.integer("condition_max_dofs", low=0), linear_floor=s.boolean("linear_floor"),
                  polish=s.integer("polish", low=0))


def _petsc_options(raw, path):
    """(name, value) string pairs, each checked (petsc_options.check); errors name the option's key."""
    if not isinstance(raw, dict):
        raise ConfigError(path, "must be a mapping of PETSc option names to values")
    try:
        options = tuple(petsc.check(str(name).lstrip("-"), value) for name, value in raw.items())
    except petsc.OptionError as err:
        raise ConfigError(f"{path}.{err.name}", str(err)) from None
    names = [str(name).lstrip("-") for name in raw]
    for i, (key, _) in enumerate(options):  # PETSc would keep one of them, silently
        first = next(j for j, (other, _) in enumerate(options) if other == key)
        if first < i:
            raise ConfigError(f"{path}.{names[i]}", f"is {names[first]} again (PETSc option names are "
                                                    "case-insensitive, the study's prefix is implied)")
    return options


def _continuation(raw, path):
    check.keys(raw, path, optional=keys_of(Continuation))
    s = check.Section(raw, path, Continuation)
    factor = s.number("factor", positive=True)
    if factor >= 1:
        raise ConfigError(s.at("factor"), f"must be < 1 (eps decreases), got {factor:g}")
    return Continuation(start=s.number("start", positive=True), factor=factor,
                        max_steps=s.integer("max_steps", low=1))


def output(raw, path):
    check.keys(raw, path, optional=keys_of(Output))
    s = check.Section(raw, path, Output)
    return Output(dir=s.string("dir"), plots=s.boolean("plots"), fields=s.boolean("fields"),
                  digits=s.integer("digits", low=1), columns=_columns(s.get("columns"), s.at("columns")),
                  figure_width=length(s.get("figure_width"), s.at("figure_width")))


def _columns(value, path):
    """paper | all | a non-empty list of column names (report checks the names against the table)."""
    if isinstance(value, list):
        if not value or not all(isinstance(c, str) and c for c in value):
            raise ConfigError(path, f"must be {' | '.join(TABLE_COLUMNS)} or a non-empty list of column names")
        return tuple(value)
    return check.choice(value, path, TABLE_COLUMNS)


def table_columns(text, path):
    """A command-line value: paper, all, or comma-separated column names."""
    return _columns(text if text in TABLE_COLUMNS else [c.strip() for c in text.split(",")], path)


LENGTH_UNITS = {"pt": 1.0, "in": 72.27, "cm": 72.27 / 2.54, "mm": 72.27 / 25.4}  # TeX points


def length(value, path):
    """A length in TeX points from a number (pt) or a string with a unit: "390pt", "5.4in", "12cm"."""
    text = str(value).strip()
    unit = next((u for u in LENGTH_UNITS if text.endswith(u)), "")
    try:
        points = float(text[:len(text) - len(unit)]) * LENGTH_UNITS.get(unit, 1.0)
    except ValueError:
        raise ConfigError(path, f"must be a length such as 390pt or 5.4in, got {check.show(value)}") from None
    if not 0 <= points <= 2000 or (points and points < 100):
        raise ConfigError(path, f"must be between 100pt and 2000pt, got {check.show(value)}")
    return points


def verification(raw, path, problem):
    check.keys(raw, path, optional=keys_of(Verification))
    s = check.Section(raw, path, Verification)
    data_only = isinstance(problem, dict) and "exact" not in problem
    for name in ("reference_refinements", "reference_epsilon"):
        if name in raw and not data_only:
            raise ConfigError(s.at(name), "only meaningful without problem.exact (data-only scenes)")
    measures = s.get("measures")
    if measures is not None:
        if not isinstance(measures, list):
            raise ConfigError(s.at("measures"), f"must be a list of {', '.join(MEASURES)}")
        measures = tuple(check.choice(m, f"{path}.measures[{i}]", MEASURES) for i, m in enumerate(measures))
        if len(set(measures)) != len(measures):
            raise ConfigError(s.at("measures"), f"lists a measure twice: {list(measures)}")
    return Verification(fit_levels=s.integer("fit_levels", low=2), tolerance=s.number("tolerance", low=0.0),
                        measures=measures,
                        reference_refinements=s.integer("reference_refinements", low=0,
                                                        high=MAX_REFERENCE_REFINEMENTS),
                        reference_epsilon=s.choice("reference_epsilon", REFERENCE_EPSILONS),
                        regular=s.boolean("regular"))


def expect(raw, path, problem):
    check.keys(raw, path, required=("rates",), optional=keys_of(Expect))
    s = check.Section(raw, path, Expect)
    rates = raw["rates"]
    if not isinstance(rates, dict) or not rates:
        raise ConfigError(s.at("rates"), "must be a mapping of norm to rate, e.g. {L2: 2.0, H1: 1.0}")
    data_only = isinstance(problem, dict) and "exact" not in problem
    norms = REFERENCE_NORMS if data_only else ERROR_NORMS + REFERENCE_NORMS[-2:]  # diff_* in both
    for norm in rates:
        if norm not in norms:
            scene = "a data-only scene (no exact solution)" if data_only else "a manufactured scene"
            raise ConfigError(f"{path}.rates.{norm}", f"not a rate column of {scene}; one of {', '.join(norms)}")
    return Expect(rates=tuple((norm, check.number(rate, f"{path}.rates.{norm}")) for norm, rate in rates.items()),
                  tolerance=s.number("tolerance", low=0.0))
