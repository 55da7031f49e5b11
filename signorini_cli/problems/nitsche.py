"""Nitsche's method for the Signorini problem u ≤ 0, ∂_n u ≤ 0, u ∂_n u = 0 on Γ_C (Chouly & Hild 2013,
SINUM; Chouly, Hild & Renard 2015, Math. Comp.): the condition, written ∂_n u = −(1/γ)[u − γ∂_n u]_+, enters
the weak form consistently,

    ∫ ∇u_h·∇v − θ∫_Γc γ ∂_n u_h ∂_n v + ∫_Γc (1/γ)[u_h − γ∂_n u_h]_+ (v − θγ∂_n v) = ∫ f v,

γ = γ0 h_K (h_K the diameter of the cell owning the facet); θ = 1 symmetric, 0 incomplete, −1 skew-symmetric.
The θ term is linear (UFL, in the stiffness); for P1, P = u_h − γ∂_n u_h is linear on each facet, so
NitscheTerm integrates the kinked term and its Jacobian exactly (contact.moments)."""
import math

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from ..analysis import rates
from ..config import method_nitsche
from ..meshing.meshes import CONTACT
from . import contact, forms as forms_, measure

NAME = "nitsche"
EPSILON = False  # no ε: the discrete problem is Signorini's itself
MEASURES = method_nitsche.MEASURES  # those it has (config/method_nitsche.py)
REFERENCES = "Chouly & Hild 2013 (SINUM); Chouly, Hild & Renard 2015 (Math. Comp.)"


def parameters(cfg):
    """The method's parameters in a line."""
    return f"Nitsche θ = {cfg.nitsche.theta:g}, γ0 = {cfg.nitsche.gamma0:g}"


def forms(cfg, boundary, eps):
    """F(u_h; v) of the weak form above: −θ∫γ ∂_n u_h ∂_n v in UFL (constant on each P1 facet: exact), the
    kinked term beside UFL (NitscheTerm)."""
    theta, gamma0 = cfg.nitsche.theta, cfg.nitsche.gamma0
    u_h = boundary.u_h
    v = ufl.TestFunction(u_h.function_space)
    gamma = gamma0 * ufl.CellDiameter(u_h.function_space.mesh)
    linear = None if theta == 0 else -theta * gamma * boundary.flux(u_h) * boundary.flux(v) * boundary.ds_c
    term = NitscheTerm(u_h, boundary.domain, theta, gamma0)
    return forms_.assemble(boundary, None, term, False, boundary.load, linear)


class NitscheTerm:
    """∫_Γc (1/γ)[P]_+ (v − θγ∂_n v), P = u_h − γ∂_n u_h, on the rank's owned Γ_C facets, with its Jacobian
    (1/γ)∫ H(P) (φ_k − γ∂_n φ_k)(φ_j − θγ∂_n φ_j): exact for P1, where ∂_n φ_j is constant on a facet and P
    linear. Rows are the dofs of the cell owning each facet (∂_n v couples them all)."""

    alpha = 1.0  # [P]_+ to the first power: its Jacobian jumps, as the penalty's for α = 1 (no Lipschitz J)

    def __init__(self, u_h, domain, theta, gamma0):
        self.u_h, self.theta = u_h, theta
        V = u_h.function_space
        self.facet_dofs, self.points = measure.contact_facet_dofs(V, domain.facet_tags, CONTACT)
        self.sizes = measure.facet_sizes(self.points)
        self.rows, self.flux, self.position, h_K = cell_geometry(V, domain.facet_tags, self.facet_dofs)
        self.gamma = gamma0 * h_K

    def prepare(self):
        """No data to prepare: the term depends on u_h alone."""

    def argument(self, u):
        """P = u_h − γ∂_n u_h at each facet's vertices (facets, n+1) from the local array u."""
        normal_derivative = np.einsum("fj,fj->f", self.flux, u[self.rows])
        return u[self.facet_dofs] - (self.gamma * normal_derivative)[:, None]

    def _on_cell(self, values):
        """Facet-vertex values (facets, n+1) placed at their positions among the cell's dofs (facets, n+2)."""
        out = np.zeros(self.rows.shape)
        out[np.arange(len(values))[:, None], self.position] = values
        return out

    def residual(self, u):
        """Per facet, on the cell's dofs: (1/γ)∫[P]_+ φ_j − θ ∂_n φ_j ∫[P]_+."""
        m0, m1, _ = contact.moments(self.argument(u), 1.0)
        return self.sizes[:, None] * (self._on_cell(m1) / self.gamma[:, None] - self.theta * self.flux * m0[:, None])

    def jacobian(self, u):
        """Per facet (facets, k, k), row j (test), column k (trial): (1/γ)[∫Hφ_jφ_k − θγ c_j∫Hφ_k − γ c_k∫Hφ_j
        + θγ² c_j c_k ∫H], c = ∂_n φ on the facet, H the Heaviside of P."""
        h0, h1, h2 = contact.moments(self.argument(u), 0.0)
        a2 = np.zeros((len(h0),) + (self.rows.shape[1],) * 2)
        a2[np.arange(len(h0))[:, None, None], self.position[:, :, None], self.position[:, None, :]] = h2
        a1, c, g = self._on_cell(h1), self.flux, self.gamma[:, None, None]
        J = (a2 - self.theta * g * c[:, :, None] * a1[:, None, :] - g * a1[:, :, None] * c[:, None, :]
             + self.theta * g**2 * c[:, :, None] * c[:, None, :] * h0[:, None, None])
        return self.sizes[:, None, None] * J / g

    def add_residual(self, b):
        """b += the residual at u_h (local array, ghosts included: before b's reverse ghost update)."""
        np.add.at(b, self.rows, self.residual(self.u_h.x.array))

    def add_jacobian(self, A, fixed):
        """A += the Jacobian (ADD, local indices) off the rows and columns of the Dirichlet dofs `fixed`.
        Collective."""
        A.assemblyBegin(PETSc.Mat.AssemblyType.FLUSH)  # after the INSERTed identity rows of Γ_D
        A.assemblyEnd(PETSc.Mat.AssemblyType.FLUSH)
        if len(self.rows):
            index = np.where(fixed[self.rows], -1, self.rows).astype(PETSc.IntType)  # PETSc skips index -1
            A.setValuesLocalRCV(index, index, self.jacobian(self.u_h.x.array), addv=PETSc.InsertMode.ADD)

    def contact_force(self):
        """∫_Γc (1/γ)[P]_+ = −∫_Γc σ_h, summed over ranks: the discrete contact force."""
        m0 = contact.moments(self.argument(self.u_h.x.array), 1.0)[0] if len(self.rows) else np.zeros(0)
        return self.u_h.function_space.mesh.comm.allreduce(float(np.sum(self.sizes * m0 / self.gamma)), op=MPI.SUM)

    def contact_measure(self):
        """|{P > 0} ∩ Γ_C|, where the contact pressure (1/γ)[P]_+ is positive (exact for P1)."""
        return measure.vertex_contact_measure(self.u_h.function_space.mesh.comm, self.argument(self.u_h.x.array),
                                              self.points)


def cell_geometry(V, facet_tags, facet_dofs):
    """For each owned Γ_C facet (in contact_facet_dofs' order): the dofs of the cell owning it, ∂_n φ_j of
    its P1 basis functions (n the facet's outward normal), the positions of the facet's dofs among the cell's,
    and the cell's diameter h_K (the largest distance between two of its vertices, as ufl.CellDiameter)."""
    msh = V.mesh
    tdim, d = msh.topology.dim, msh.geometry.dim
    facets = facet_tags.indices[facet_tags.values == CONTACT]
    facets = facets[facets < msh.topology.index_map(tdim - 1).size_local]
    msh.topology.create_connectivity(tdim - 1, tdim)
    f2c = msh.topology.connectivity(tdim - 1, tdim)
    cells = f2c.array[f2c.offsets[facets]]
    cell_dofs = V.dofmap.list.array.reshape(-1, tdim + 1)[cells]
    x = V.tabulate_dof_coordinates()[cell_dofs][..., :d]  # (facets, d+1, d): the P1 dofs are the vertices
    edges = x[:, 1:] - x[:, :1]
    grads = np.linalg.inv(edges).transpose(0, 2, 1) if len(x) else np.zeros((0, d, d))  # ∇λ_1 .. ∇λ_d
    grads = np.concatenate((-grads.sum(axis=1, keepdims=True), grads), axis=1)
    position = np.argmax(cell_dofs[:, None, :] == facet_dofs[:, :, None], axis=2)
    opposite = tdim * (tdim + 1) // 2 - position.sum(axis=1)  # the cell's vertex off the facet
    inward = grads[np.arange(len(x)), opposite]  # ∇λ of the opposite vertex points into the cell
    n = -inward / np.linalg.norm(inward, axis=1)[:, None] if len(x) else np.zeros((0, d))
    flux = np.einsum("fjk,fk->fj", grads, n)
    h_K = np.linalg.norm(x[:, :, None] - x[:, None, :], axis=-1).max(axis=(1, 2)) if len(x) else np.zeros(0)
    return cell_dofs, flux, position, h_K


def contact_errors(cfg, comm, points, w_h, w, eps, seminorm):
    """Γ_C errors of w_h against w on the facets `points`: ||w − w_h||_{L2(Γ_C)}, exact (measure.contact_errors,
    whose L2 term depends on neither α nor ε; the penalty's energy and L^{α+1} terms have no meaning here)."""
    return {"L2_gc": measure.contact_errors(comm, points, w_h, w, math.inf, 1.0, seminorm)["L2_gc"]}


def quantities(cfg, forms, eps, wanted):
    """The contact set {P > 0} and the contact force ∫(1/γ)[P]_+ of the method's own term."""
    found, term = {}, forms.contact
    if "contact_measure" in wanted:
        found["contact_measure"] = term.contact_measure()
    if "contact_force" in wanted:
        found["contact_force"] = term.contact_force()
    return found


def expected(cfg, norm):
    """The proven rates: |u − u_h|_H1 = O(h^{1/2+ν}) for u ∈ H^{3/2+ν}, 0 < ν ≤ 1/2 (P1: O(h) for u ∈ H^2):
    for θ = −1 with any γ0 > 0; for θ = 1, 0 with γ0 small enough, a bound the study does not compute. Errors
    against a reference and successive differences are bounded as H1 is (no ε changes between levels)."""
    if rates.base_norm(norm) != "H1":
        return rates.Expected(None, reason=f"Nitsche's analysis proves no rate for {norm}")
    if not cfg.verification.regular:
        return rates.Expected(None, reason="the rate assumes u in H^2 (verification.regular: false)")
    conditions = "P1, u in H^2 (ν = 1/2), " + ("any γ0 > 0" if cfg.nitsche.theta == -1 else "γ0 small enough")
    unchecked = "" if cfg.nitsche.theta == -1 else f"γ0 = {cfg.nitsche.gamma0:g} below the proof's bound"
    return rates.Expected(1.0, reference=REFERENCES, conditions=conditions, unchecked=unchecked)
