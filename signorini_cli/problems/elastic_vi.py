"""The Signorini problem of elasticity, the ε → 0 limit of problems/elasticity.py, on the P1 space: u_h·n ≤ g0
at the Γ_C nodes of a face whose outward normal is ± an axis e_k, where u·n = ±u_k is one component and the
constraint is a bound on it (vinewtonrsls with variable bounds, as problems/vi.py for the scalar problem). The
physical problem: f = 0, u = 0 on Γ_D, σ_t = 0 on Γ_C, driven by the gap g0 (negative where the obstacle
starts inside the body)."""
from dataclasses import dataclass

import numpy as np
import ufl
from mpi4py import MPI

from dolfinx import fem, la
from petsc4py import PETSc

from ..config import expressions
from ..meshing.meshes import FACES_2D, FACES_3D
from ..solve import strategies
from . import elasticity, measure, vi
from .forms import QUADRATURE_DEGREE, Forms

CONTACT_TOL = 1e-12  # relative to max|g0|: a node is in contact when u·n − g0 is within it of 0 (at the bound)


def space(cfg, msh):
    """P1 vector Lagrange: the nodal bounds are u·n ≤ g0 on Γ_C for P1 only."""
    return elasticity.space(cfg, msh)


def exact_solution(cfg, msh):
    """None: the physical problem has no manufactured Signorini solution."""
    return None


def dirichlet_condition(V, domain, u_exact):
    """u = 0 on Γ_D."""
    return elasticity.dirichlet_condition(V, domain, None)


def errors(u_h, u_exact, h, degree=None):
    """{'L2', 'H1'} of u − u_h (the study's interface; the physical problem has no u)."""
    return measure.errors(u_h, u_exact, h, degree)


def face(cfg):
    """(k, s): the axis of Γ_C's outward normal n = s e_k (the face x_k = 0: s = −1, x_k = 1: s = 1)."""
    axis, value = (FACES_2D if cfg.dimension == 2 else FACES_3D)[cfg.contact]
    return axis, (-1.0 if value == 0.0 else 1.0)


@dataclass(frozen=True)
class Constraint:
    """s u_k ≤ g0 at the Γ_C nodes: the local dofs of u_k there, g0 at them, the sign s of n = s e_k."""
    dofs: np.ndarray
    g0: np.ndarray
    s: float


def forms(cfg, domain, u_h):
    """F(u_h; v) = ∫ σ(u_h):ε(v) (f = 0) and J = dF/du; the contact lives in the bounds (Forms.gap: the
    Constraint)."""
    v, du = ufl.TestFunction(u_h.function_space), ufl.TrialFunction(u_h.function_space)
    F = ufl.inner(elasticity.stress(cfg, u_h), elasticity.strain(v)) * ufl.dx(domain=domain.mesh)
    return Forms(F, ufl.derivative(F, u_h, du), None, domain.ds_c(QUADRATURE_DEGREE),
                 near_nullspace=elasticity.rigid_motions(u_h.function_space),
                 gap=Constraint(*contact_dofs(cfg, u_h.function_space, domain), face(cfg)[1]))


def problem(cfg, domain, u_h, bc):
    """The VI as a strategies.Problem: u_k ≥ −g0 (s = −1) or u_k ≤ g0 (s = 1) at the Γ_C nodes. Returns
    (Problem, Forms)."""
    forms_ = forms(cfg, domain, u_h)
    lower, upper = bounds(forms_.gap, u_h.function_space, bc)
    return strategies.problem(forms_, u_h, [bc], None, 0.0, cfg.dimension, bounds=(lower, upper)), forms_


def solve(cfg, domain, u_h, bc, previous=None, monitor=None):
    """Solve the VI for u_h by the configured strategy; (Outcome, Forms)."""
    return vi.solved(cfg, problem(cfg, domain, u_h, bc), previous, monitor)


def contact_dofs(cfg, V, domain):
    """(dofs, g0): the local dofs of the normal component u_k at the Γ_C nodes, and the gap there."""
    axis, _ = face(cfg)
    nodes = vi.contact_dofs(V, domain)  # blocks: one per node
    x = V.tabulate_dof_coordinates()[nodes]
    g0 = np.broadcast_to(elasticity.gap(cfg, x.T, expressions.numpy_functions()), len(nodes))
    return nodes * V.dofmap.index_map_bs + axis, np.asarray(g0, dtype=float)


def bounds(constraint, V, bc):
    """(lower, upper): s u_k ≤ g0 at the Γ_C nodes, unbounded elsewhere, Dirichlet dofs pinned to 0."""
    s, dofs, g0 = constraint.s, constraint.dofs, constraint.g0
    lower = la.create_petsc_vector(V.dofmap.index_map, V.dofmap.index_map_bs)
    upper = lower.duplicate()
    with lower.localForm() as lo, upper.localForm() as up:
        lo.set(-PETSc.INFINITY)
        up.set(PETSc.INFINITY)
        (up if s > 0 else lo).array[dofs] = s * g0
        pinned, _ = bc.dof_indices()
        lo.array[pinned] = up.array[pinned] = bc.g.x.array[pinned]
    return lower, upper


def contact_state(forms_, u_h, domain, bc):
    """The contact set (Γ_C nodes at the bound) and the pressure: λ_i = −s F(u_h)_i on u_k's dof, the node's
    share of the contact force (σn = −p n on Γ_C), w_i = ∫_Γc φ_i; MPI-reduced."""
    V = u_h.function_space
    s, dofs, g0 = forms_.gap.s, forms_.gap.dofs, forms_.gap.g0
    owned = dofs < V.dofmap.index_map.size_local * V.dofmap.index_map_bs
    pinned, _ = bc.dof_indices()
    keep = owned & ~np.isin(dofs, pinned)
    dofs, g0 = dofs[keep], g0[keep]
    residual = vi._assembled(forms_.F)
    scalar = fem.FunctionSpace(domain.mesh, ("Lagrange", 1))
    lumped = vi._assembled(ufl.TestFunction(scalar) * forms_.ds_c)
    with residual.localForm() as r, lumped.localForm() as m:
        lam, weight = -s * r.array[dofs], m.array[dofs // V.dofmap.index_map_bs].copy()
    residual.destroy()
    lumped.destroy()
    comm = domain.mesh.comm
    scale = comm.allreduce(float(np.abs(g0).max(initial=0.0)), op=MPI.MAX) or 1.0
    touching = s * u_h.x.array[dofs] - g0 >= -CONTACT_TOL * scale
    return vi.Contact(nodes=comm.allreduce(int(np.count_nonzero(touching)), op=MPI.SUM),
                      measure=comm.allreduce(float(weight[touching].sum()), op=MPI.SUM),
                      force=comm.allreduce(float(lam.sum()), op=MPI.SUM),
                      pressure_max=comm.allreduce(float((lam / weight).max(initial=-np.inf)), op=MPI.MAX))


def model_differences(cfg, domain, u_eps, u_S, ds_c):
    """||u_{ε,h} − u_{S,h}|| in L2(Ω), H1 (seminorm), L2(Γ_C), and the largest penetration
    max [u_{ε,h}·n − g0]_+ at the Γ_C nodes."""
    found = measure.difference_norms(u_eps, u_S)
    e = u_eps - u_S
    found["L2_gamma_c"] = np.sqrt(abs(measure.integrate(ufl.inner(e, e), ds_c)))
    _, s = face(cfg)
    dofs, g0 = contact_dofs(cfg, u_eps.function_space, domain)
    local = float(np.maximum(s * u_eps.x.array[dofs] - g0, 0.0).max(initial=0.0))
    found["penetration"] = domain.mesh.comm.allreduce(local, op=MPI.MAX)
    return found
