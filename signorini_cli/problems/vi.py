"""The discrete Signorini problem (paper eq. (8)) on the P1 space: u_h <= 0 at the Γ_C nodes,
solved by PETSc's reduced-space semismooth Newton (vinewtonrsls) with variable bounds."""
from dataclasses import dataclass

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import fem, la
from dolfinx.fem import petsc as fem_petsc

from ..solve import strategies
from . import compliance, element, measure
from .forms import QUADRATURE_DEGREE, Forms

# A Γ_C node is in contact when its bound is active: vinewtonrsls puts active nodes exactly on the
# bound (measured on the manufactured u_S, N = 16..256: contact nodes are 0.0, the free node nearest to
# the contact set is at −1.9e-6 for N = 256), so round-off is the only margin needed.
CONTACT_TOL = 1e-14


@dataclass(frozen=True)
class Contact:
    """The contact state of a discrete Signorini solution, from its Γ_C nodes (MPI-reduced)."""
    nodes: int             # Γ_C nodes in contact (u_h = 0, bound active)
    measure: float         # lumped measure of the contact set: Σ_{contact} ∫_Γc φ_i
    force: float           # total contact force Σ_i λ_i = −∫_Γc ∂_n u_h
    pressure_max: float    # max_i λ_i / ∫_Γc φ_i, the discrete contact pressure −∂_n u_h


def space(cfg, msh):
    """P1: the discrete VI bounds u_h <= 0 at the Γ_C nodes, which is u_h <= 0 on Γ_C for P1 only."""
    return element.space(msh, 1)


def exact_solution(cfg, msh):
    """u_S as UFL, or None (validated: a Signorini solution does not depend on eps)."""
    return compliance.exact_solution(cfg, msh, None)


def dirichlet_condition(V, domain, u_exact):
    """u = u_S on Γ_D (manufactured scenes), else 0."""
    return compliance.dirichlet_condition(V, domain, u_exact)


def errors(u_h, u_exact, h, degree=None):
    """{'L2', 'H1'} of u_S − u_h."""
    return measure.errors(u_h, u_exact, h, degree)


def forms(cfg, domain, u_h):
    """F(u_h; v) = ∫ ∇u_h·∇v − ∫ f v and J = dF/du; the contact lives in the bounds, not in F."""
    msh = domain.mesh
    v, du = ufl.TestFunction(u_h.function_space), ufl.TrialFunction(u_h.function_space)
    degree = domain.quadrature[0] if domain.quadrature else QUADRATURE_DEGREE  # as the data need (posed)
    dx = ufl.Measure("dx", domain=msh, metadata={"quadrature_degree": degree})
    u_exact = exact_solution(cfg, msh)
    f, _ = compliance.data(cfg, msh, None, u_exact, ufl.FacetNormal(msh))  # g = 0: homogeneous contact
    F = ufl.inner(ufl.grad(u_h), ufl.grad(v)) * dx - f * v * dx
    return Forms(F, ufl.derivative(F, u_h, du), u_exact, domain.ds_c(QUADRATURE_DEGREE))


def problem(cfg, domain, u_h, bc):
    """The VI as a strategies.Problem: the forms without contact, u_h <= 0 at the Γ_C nodes as bounds
    (vinewtonrsls; the user's petsc_options still win). Returns (Problem, Forms)."""
    forms_ = forms(cfg, domain, u_h)
    lower, upper = bounds(u_h.function_space, domain, bc)
    return strategies.problem(forms_, u_h, [bc], None, 0.0, cfg.dimension, bounds=(lower, upper)), forms_


def solve(cfg, domain, u_h, bc, previous=None, monitor=None):
    """Solve the VI for u_h by the configured strategy, `previous` being the last level's solution (the
    nested guess) or None; return (Outcome, Forms)."""
    return solved(cfg, problem(cfg, domain, u_h, bc), previous, monitor)


def solved(cfg, posed, previous=None, monitor=None):
    """Solve a VI posed as (Problem, Forms) by the configured strategy, its bound vectors destroyed after;
    (Outcome, Forms)."""
    vi_problem, forms_ = posed
    try:
        outcome = strategies.solve(cfg.solver, vi_problem, previous, monitor)
    finally:
        for bound in vi_problem.bounds:
            bound.destroy()
    return outcome, forms_


def bounds(V, domain, bc):
    """(lower, upper): −inf <= u_i <= 0 at Γ_C dofs, unbounded elsewhere, Dirichlet dofs pinned to u_D."""
    lower = la.create_petsc_vector(V.dofmap.index_map, V.dofmap.index_map_bs)
    upper = lower.duplicate()
    with lower.localForm() as lo, upper.localForm() as up:
        lo.set(-PETSc.INFINITY)
        up.set(PETSc.INFINITY)
        up.array[contact_dofs(V, domain)] = 0.0
        dofs, _ = bc.dof_indices()
        lo.array[dofs] = up.array[dofs] = bc.g.x.array[dofs]  # lower == upper: PETSc keeps them fixed
    return lower, upper


def contact_dofs(V, domain):
    """Local indices (owned and ghost) of the dofs on Γ_C."""
    return fem.locate_dofs_topological(V, domain.mesh.topology.dim - 1, domain.facets())


def contact_state(forms_, u_h, domain, bc):
    """The contact set (Γ_C nodes at the bound) and the discrete pressure, MPI-reduced."""
    nodes, lam, weight = nodal_pressure(forms_, u_h, domain, bc)
    touching = u_h.x.array[nodes] >= -CONTACT_TOL
    comm = domain.mesh.comm
    return Contact(nodes=comm.allreduce(int(np.count_nonzero(touching)), op=MPI.SUM),
                   measure=comm.allreduce(float(weight[touching].sum()), op=MPI.SUM),
                   force=comm.allreduce(float(lam.sum()), op=MPI.SUM),
                   pressure_max=comm.allreduce(float((lam / weight).max(initial=-np.inf)), op=MPI.MAX))


def nodal_pressure(forms_, u_h, domain, bc):
    """(nodes, λ, w) at the owned Γ_C nodes off Γ_D: λ_i = −F(u_h)_i = −∫_Γc ∂_n u_h φ_i (the VI's
    multiplier) and w_i = ∫_Γc φ_i, so λ_i / w_i is the discrete contact pressure −∂_n u_h."""
    V = u_h.function_space
    dofs = contact_dofs(V, domain)
    dirichlet, _ = bc.dof_indices()  # a Dirichlet dof carries a reaction, not a contact pressure
    nodes = np.setdiff1d(dofs[dofs < V.dofmap.index_map.size_local], dirichlet)
    residual = _assembled(forms_.F)
    lumped = _assembled(ufl.TestFunction(V) * forms_.ds_c)
    with residual.localForm() as r, lumped.localForm() as m:
        lam, weight = -r.array[nodes], m.array[nodes].copy()
    residual.destroy()
    lumped.destroy()
    return nodes, lam, weight


def pressure_error(forms_, u_h, domain, bc, face):
    """Lumped L2(Γ_C) error of the discrete pressure against −∂_n u_S (u_S smooth up to Γ_C)."""
    V = u_h.function_space
    axis, value = face
    outward = -1.0 if value == 0.0 else 1.0  # the unit square/cube face x[axis] = value
    p_exact = fem.Function(V)
    p_exact.interpolate(fem.Expression(-outward * ufl.grad(forms_.u_exact)[axis],
                                       V.element.interpolation_points()))
    nodes, lam, weight = nodal_pressure(forms_, u_h, domain, bc)
    local = float(np.sum(weight * (lam / weight - p_exact.x.array[nodes]) ** 2))
    return float(np.sqrt(domain.mesh.comm.allreduce(local, op=MPI.SUM)))


def _assembled(form):
    """An assembled vector, ghost contributions summed into the owners."""
    vector = fem_petsc.assemble_vector(fem.form(form))
    vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return vector


def model_differences(cfg, domain, u_eps, u_S, ds_c):
    """The model error of an ε-sweep on `domain` (measure.model_differences, its penetration at the Γ_C dofs)."""
    return measure.model_differences(u_eps, u_S, ds_c, contact_dofs(u_eps.function_space, domain))
