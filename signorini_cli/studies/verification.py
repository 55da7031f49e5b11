"""Per-level verification measures beyond L2/H1: Γ_C errors and quantities, successive differences, and
errors against a reference solution for data-only scenes; written as Level.extra columns with rates."""
import ufl
from mpi4py import MPI

from ..config import names
from ..meshing.meshes import CONTACT
from ..problems import contact, hertz, measure, profile
from ..problems.registry import problem_of
from . import reference

CONTACT_ERRORS = tuple(c for m in names.MEASURES if m.kind == "error" and m.contact for c in m.columns)
NEEDS_CONTACT = tuple(m.key for m in names.MEASURES if m.contact)
QUANTITIES = tuple(c for m in names.MEASURES if m.kind == "quantity" for c in m.columns)  # values, no rates
REFERENCE_ERRORS = ("ref_err_L2", "ref_err_H1")  # ||u_ref(k-1) - u_ref(k)||: how exact each reference is


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
            points, w_h, w_exact, seminorm = self._contact_variable(u_h, domain, forms, level)
            found = measure.contact_errors(domain.mesh.comm, points, w_h, w_exact, level.eps, self.cfg.alpha,
                                           seminorm)
            errors.update({k: v for k, v in found.items() if _wanted(k, wanted)})
        # a level that did not converge gets no reference solve and is no base for differences
        if self.reference is not None and converged:
            errors.update(self._against_reference(level, domain, u_h, wanted, has_contact))
        if "diff" in wanted and self.previous is not None and converged:
            errors.update(reference.successive_differences(self.previous, u_h))
        quantities = self._quantities(level, domain, u_h, forms, wanted)
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

    def _quantities(self, level, domain, u_h, forms, wanted):
        """Γ_C quantities of u_h, exact: its largest value, the measure of {u_h > 0} and ∫[u_h]_+^beta
        (contact.positive_power: for P1 the closed form of the solve's own penalty term)."""
        found = {}
        if forms.gap is not None:  # elasticity: w_h = u_h·n − g0 at the Γ_C facets' vertices
            return self._normal_quantities(level, domain, forms, wanted)
        dofs, points = measure.contact_facet_dofs(u_h.function_space, domain.facet_tags, CONTACT)
        if "penetration" in wanted:
            found["penetration"] = measure.penetration(u_h, dofs)
        if "contact_measure" in wanted:
            found["contact_measure"] = measure.contact_measure(u_h, dofs, points)
        alpha, comm, degree = self.cfg.alpha, domain.mesh.comm, self.cfg.element.degree
        values = u_h.x.array[dofs]
        if "contact_force" in wanted:
            found["contact_force"] = contact.positive_power(comm, values, points, alpha, degree) / level.eps
        if "energy" in wanted:
            penalty = contact.positive_power(comm, values, points, alpha + 1, degree) / (alpha + 1)
            found["energy"] = self._energy(level, domain, u_h, forms, penalty)
        return found

    def _normal_quantities(self, level, domain, forms, wanted):
        """Γ_C quantities of an elastic u_h through w_h = u_h·n − g0, from its facet dof values: penetration,
        the contact set and (1/eps)∫[w_h]_+^alpha, all exact for P1 and P2 (no potential energy), and with
        problem.hertz_radius the half-width and peak pressure against Hertz's (problems/hertz.py, P1)."""
        comm, found, degree = domain.mesh.comm, {}, self.cfg.element.degree
        values, points = forms.gap.dof_values(), forms.gap.term.points
        if "penetration" in wanted:
            found["penetration"] = measure.vertex_penetration(comm, values, degree)
        if "contact_measure" in wanted:
            found["contact_measure"] = measure.vertex_contact_measure(comm, values, points, degree)
        if "contact_force" in wanted:
            force = contact.positive_power(comm, values, points, self.cfg.alpha, degree)
            found["contact_force"] = force / level.eps
        if "hertz" in wanted:
            found.update(hertz.quantities(self.cfg, forms.gap.term, level.eps))
        return found

    def _contact_variable(self, u_h, domain, forms, level):
        """(points, w_h, w_ex, seminorm) the Γ_C errors read: the Γ_C facets' vertices, u_h's facet dof
        values, u_ex(facets, x) and |e|_H1 for the scalar problem; for elasticity w = u·n − g0 (w_h at the
        facets' dofs, as the solve's contact term has it) and the energy seminorm a(e, e)^(1/2) of e = u − u_h
        (Lemma 3.1's analogue)."""
        if forms.gap is None:
            dofs, points = measure.contact_facet_dofs(u_h.function_space, domain.facet_tags, CONTACT)
            u_ex = problem_of(self.cfg).numpy_exact(self.cfg, domain.mesh.geometry.dim)
            vertices = points[:, :domain.mesh.topology.dim]
            return vertices, u_h.x.array[dofs], lambda facets, x: u_ex(x, level.eps), level.errors["H1"]
        msh = u_h.function_space.mesh
        degree = domain.quadrature[1] if domain.quadrature else measure.error_degree(u_h.function_space, level.h)
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": degree})
        a_ee = measure.integrate(forms.gap.energy(forms.u_exact - u_h), dx)
        vertices = forms.gap.term.points[:, :msh.topology.dim]
        return vertices, forms.gap.dof_values(), forms.gap.exact(level.eps), abs(a_ee) ** 0.5

    def _energy(self, level, domain, u_h, forms, penalty):
        msh = domain.mesh
        problem_module = problem_of(self.cfg)
        f, g = problem_module.data(self.cfg, msh, level.eps, forms.u_exact, ufl.FacetNormal(msh))
        dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": problem_module.QUADRATURE_DEGREE})
        ds_c = domain.ds_c(problem_module.QUADRATURE_DEGREE)  # g u_h: smooth data times u_h
        return measure.energy(u_h, problem_module.on_mesh(f, msh), g, level.eps, dx, ds_c, penalty)

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
