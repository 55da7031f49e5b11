"""Per-level verification measures beyond L2/H1: Γ_C errors and quantities, successive differences, and
errors against a reference solution for data-only scenes; written as Level.extra columns with rates."""
from mpi4py import MPI

from ..config import names
from ..problems import hertz, profile
from ..problems.registry import method_of
from . import reference

CONTACT_ERRORS = tuple(c for m in names.MEASURES if m.kind == "error" and m.contact for c in m.columns)
NEEDS_CONTACT = tuple(m.key for m in names.MEASURES if m.contact)
QUANTITIES = tuple(c for m in names.MEASURES if m.kind == "quantity" for c in m.columns)  # values, no rates
REFERENCE_ERRORS = ("ref_err_L2", "ref_err_H1")  # ||u_ref(k-1) - u_ref(k)||: how exact each reference is


def measures(cfg):
    """The measures a study takes: verification.measures, else the scene's defaults."""
    if cfg.verification.measures is not None:
        return cfg.verification.measures
    taken = method_of(cfg).MEASURES
    return tuple(m for m in names.defaults("exact" if cfg.problem.exact is not None else "data") if m in taken)


class Verifier:
    """Measures each level of one study; keeps what the next level needs (the previous u_h, the
    reference solutions)."""

    def __init__(self, cfg, comm=MPI.COMM_WORLD):
        self.cfg = cfg
        self.measures = measures(cfg)
        data_only = cfg.problem.exact is None
        self.reference = (reference.Reference(cfg, comm)
                          if data_only and cfg.verification.reference_refinements > 0 else None)
        self.previous = None
        self.reference_time_s = 0.0

    def measure(self, level, domain, u_h, forms):
        """Add this level's measured errors to level.errors and its columns to level.extra."""
        contact_facets = len(domain.facets())
        has_contact = domain.mesh.comm.allreduce(contact_facets, op=MPI.SUM) > 0
        wanted = [m for m in self.measures if has_contact or m not in NEEDS_CONTACT]
        converged = level.outcome.converged
        errors = {}
        if forms.u_exact is not None and has_contact and _any_error(wanted):
            points, w_h, w_exact, seminorm = forms.trace.contact_variable(level)  # w = u, or u·n − g0
            found = method_of(self.cfg).contact_errors(self.cfg, domain.mesh.comm, points, w_h, w_exact,
                                                       level.eps, seminorm)
            errors.update({k: v for k, v in found.items() if _wanted(k, wanted)})
        # a level that did not converge gets no reference solve and is no base for differences
        if self.reference is not None and converged:
            errors.update(self._against_reference(level, domain, u_h, wanted, has_contact))
        if "diff" in wanted and self.previous is not None and converged:
            errors.update(reference.successive_differences(self.previous, u_h))
        quantities = self._quantities(level, forms, wanted)
        if has_contact and converged:
            level.profile = profile.rows(self.cfg, domain, u_h, forms, level.eps, level.index)
        level.errors.update(errors)
        self._columns(level, errors, quantities, wanted, has_contact)
        if "diff" in wanted and converged:  # kept for the successive differences only: a whole level's mesh
            self.previous = u_h

    def _against_reference(self, level, domain, u_h, wanted, has_contact):
        found, converged, seconds = self.reference.measure(level.index, domain, u_h, level.eps,
                                                           has_contact and _any_error(wanted))
        self.reference_time_s = seconds
        if not converged:  # no error against a reference that is not one: the columns stay empty
            return {}
        return {k: v for k, v in found.items()
                if not k.endswith("_ref") or k in ("L2_ref", "H1_ref") or _wanted(k[:-4], wanted)}

    def _quantities(self, level, forms, wanted):
        """Γ_C quantities of u_h: the penetration max [w_h]_+ from the problem's trace (exact for P1), and the
        method's own (its contact set, contact force, energy)."""
        trace, found = forms.trace, {}
        if "penetration" in wanted:
            found["penetration"] = trace.penetration()
        found.update(method_of(self.cfg).quantities(self.cfg, forms, level.eps, wanted))
        if "hertz" in wanted:  # problem.hertz_radius: half-width and peak pressure against Hertz's (P1)
            found.update(hertz.quantities(self.cfg, forms.trace.term, level.eps))
        return found

    def _columns(self, level, errors, quantities, wanted, has_contact):
        """Table columns in a fixed order on every level: each error and its rate, then the quantities;
        values of a level that did not converge are left empty (its raw errors stay in study.h5)."""
        ok = level.outcome.converged
        for name in error_columns(self.cfg, wanted, has_contact, self.reference is not None):
            level.extra[name] = errors.get(name) if ok else None
            level.extra[f"rate_{name}"] = None
        if self.reference is not None:  # the reference's own estimated error, beside the level's
            for name in REFERENCE_ERRORS:
                level.extra[name] = errors.get(name) if ok else None
        for name in (q for q in QUANTITIES if q in quantities):
            level.extra[name] = quantities[name] if ok else None
        if self.reference is not None:
            level.extra["reference_time_s"] = self.reference_time_s if ok else 0.0  # not part of time_s


def error_columns(cfg, wanted, has_contact, with_reference):
    """The error columns (each followed by its rate) a study writes, in order."""
    columns = [name for name in CONTACT_ERRORS if has_contact and _wanted(name, wanted)]
    if cfg.problem.exact is None:  # against the reference instead of an exact solution
        columns = ["L2_ref", "H1_ref"] + [f"{name}_ref" for name in columns] if with_reference else []
    return columns + (["diff_L2", "diff_H1"] if "diff" in wanted else [])


def _wanted(name, wanted):
    """pos_gc_scaled comes with pos_gc."""
    return (name if name != "pos_gc_scaled" else "pos_gc") in wanted


def _any_error(wanted):
    return any(name in wanted for name in ("L2_gc", "pos_gc", "energy_err"))
