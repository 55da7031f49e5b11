"""Per-level verification measures beyond L2/H1: Γ_C errors and quantities, successive differences, and
errors against a reference solution for data-only scenes; written as Level.extra columns with rates."""
import ufl
from mpi4py import MPI

from ..analysis import rates
from ..config import names
from ..meshing.meshes import CONTACT
from ..problems import compliance, measure
from . import reference

CONTACT_ERRORS = tuple(c for m in names.MEASURES if m.kind == "error" and m.contact for c in m.columns)
NEEDS_CONTACT = tuple(m.key for m in names.MEASURES if m.contact)
QUANTITIES = tuple(m.key for m in names.MEASURES if m.kind == "quantity")  # no rates: values, not errors


def measures(cfg):
    """The measures a study takes: verification.measures, else the scene's defaults."""
    if cfg.verification.measures is not None:
        return cfg.verification.measures
    return names.defaults("exact" if cfg.problem.exact is not None else "data")


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
            w_h, w_exact, seminorm = _contact_variable(u_h, forms, level)
            found = measure.contact_errors(w_h, w_exact, level.eps, self.cfg.alpha,
                                           domain.ds_c(measure.ERROR_DEGREE), seminorm)
            errors.update({k: v for k, v in found.items() if _wanted(k, wanted)})
        # a level that did not converge gets no reference solve and is no base for differences
        if self.reference is not None and converged:
            errors.update(self._against_reference(level, u_h, wanted, has_contact))
        if "diff" in wanted and self.previous is not None and converged:
            errors.update(reference.successive_differences(self.previous, u_h))
        quantities = self._quantities(level, domain, u_h, forms, wanted)
        level.errors.update(errors)
        self._columns(level, errors, quantities, wanted, has_contact)
        if "diff" in wanted and converged:  # kept for the successive differences only: a whole level's mesh
            self.previous = u_h

    def _against_reference(self, level, u_h, wanted, has_contact):
        u_ref, converged, seconds = self.reference.solution(self.reference.eps_for(level.eps), u_h)
        self.reference_time_s = seconds
        found = self.reference.errors(u_h, u_ref, level.eps, has_contact and _any_error(wanted))
        if not converged:  # no error against a reference that is not one: the columns stay empty
            return {}
        return {k: v for k, v in found.items() if k in ("L2_ref", "H1_ref") or _wanted(k[:-4], wanted)}

    def _quantities(self, level, domain, u_h, forms, wanted):
        found = {}
        comm = domain.mesh.comm
        if "penetration" in wanted or "contact_measure" in wanted:
            if forms.gap is None:
                dofs, points = measure.contact_facet_dofs(u_h.function_space, domain.facet_tags, CONTACT)
                values = u_h.x.array[dofs]
            else:  # w_h = u_h·n − g0 at the Γ_C facets' vertices
                values, points = forms.gap.vertex_values(), forms.gap.term.points
            if "penetration" in wanted:
                found["penetration"] = measure.vertex_penetration(comm, values)
            if "contact_measure" in wanted:
                found["contact_measure"] = measure.vertex_contact_measure(comm, values, points)
        ds_c = domain.ds_c(measure.ERROR_DEGREE)
        if "contact_force" in wanted:
            w_h = u_h if forms.gap is None else forms.gap.w_h
            found["contact_force"] = measure.contact_force(w_h, level.eps, self.cfg.alpha, ds_c)
        if "energy" in wanted:
            found["energy"] = self._energy(level, domain, u_h, forms, ds_c)
        return found

    def _energy(self, level, domain, u_h, forms, ds_c):
        msh = domain.mesh
        f, g = compliance.data(self.cfg, msh, level.eps, forms.u_exact, ufl.FacetNormal(msh))
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": compliance.QUADRATURE_DEGREE})
        return measure.energy(u_h, f, g, level.eps, self.cfg.alpha, dx, ds_c)

    def _columns(self, level, errors, quantities, wanted, has_contact):
        """Table columns in a fixed order on every level: each error and its rate, then the quantities;
        values of a level that did not converge are left empty (its raw errors stay in study.h5)."""
        ok = level.outcome.converged
        for name in error_columns(self.cfg, wanted, has_contact, self.reference is not None):
            level.extra[name] = errors.get(name) if ok else None
            level.extra[f"rate_{name}"] = None
        for name in (q for q in QUANTITIES if q in quantities):
            level.extra[name] = quantities[name] if ok else None
        if self.reference is not None:
            level.extra["reference_time_s"] = self.reference_time_s if ok else 0.0  # not part of time_s


def _contact_variable(u_h, forms, level):
    """(w_h, w_ex, seminorm) the Γ_C errors read: u_h, u_ex and |e|_H1 for the scalar problem; for
    elasticity w = u·n − g0 and the energy seminorm a(e, e)^(1/2) of e = u − u_h (Lemma 3.1's analogue)."""
    if forms.gap is None:
        return u_h, forms.u_exact, level.errors["H1"]
    msh = u_h.function_space.mesh
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": measure.error_degree(level.h)})
    a_ee = measure.integrate(forms.gap.energy(forms.u_exact - u_h), dx)
    return forms.gap.w_h, forms.gap.w_exact, abs(a_ee) ** 0.5


def error_columns(cfg, wanted, has_contact, with_reference):
    """The error columns (each followed by its rate) a study writes, in order."""
    columns = [name for name in CONTACT_ERRORS if has_contact and _wanted(name, wanted)]
    if cfg.problem.exact is None:  # against the reference instead of an exact solution
        columns = ["L2_ref", "H1_ref"] + [f"{name}_ref" for name in columns] if with_reference else []
    return columns + (["diff_L2", "diff_H1"] if "diff" in wanted else [])


def add_rates(levels):
    """Fill rate_<column> of every extra error column from the levels' measured h."""
    if not levels:
        return
    h = [lv.h for lv in levels]
    ok = [lv.outcome.converged for lv in levels]
    for name in [k for k in levels[0].extra if f"rate_{k}" in levels[0].extra]:
        for lv, rate in zip(levels, rates.observed(h, [lv.extra.get(name) for lv in levels], ok)):
            lv.extra[f"rate_{name}"] = rate


def _wanted(name, wanted):
    """pos_gc_scaled comes with pos_gc."""
    return (name if name != "pos_gc_scaled" else "pos_gc") in wanted


def _any_error(wanted):
    return any(name in wanted for name in ("L2_gc", "pos_gc", "energy_err"))
