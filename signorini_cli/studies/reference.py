"""Reference solutions for scenes given by their data only: each level's problem solved again on its own
mesh refined 1, ..., k times (k = verification.reference_refinements), the level moved onto them by an
exact (nested) transfer."""
import dataclasses
import logging
import time

from mpi4py import MPI

from dolfinx import fem

from ..config import MESH_KINDS
from ..meshing import meshes, refinement
from ..meshing.meshes import CONTACT
from ..problems import measure
from ..problems.registry import problem_of
from ..solve import strategies
from ..solve.transfer import transfer

logger = logging.getLogger(__name__)


class Reference:
    """Each level's reference at a fixed depth k: once the rates settle, a level's distance to its
    reference is a fixed fraction of its error, e (1 - 2^-pk), the same on every level, so the fitted rate
    does not depend on k (a reference at one depth below the finest level would bias the finest levels).
    The reference one refinement shallower gives the same columns at depth k - 1 (suffix _shallow) and
    the reference's own estimated error, ref_err_* = ||u_ref(k-1) - u_ref(k)||."""

    def __init__(self, cfg, comm=MPI.COMM_WORLD):
        self.cfg, self.comm = cfg, comm
        self.depth = cfg.verification.reference_refinements

    def eps_for(self, level_eps, domain):
        """The eps of a reference on `domain` for a level with eps = level_eps: the level's own
        (reference_epsilon: per_level) or the law's on the reference mesh (fixed)."""
        if self.cfg.verification.reference_epsilon == "per_level":
            return level_eps
        return self.cfg.epsilon(domain.h)

    def measure(self, index, domain, u_h, level_eps, with_contact):
        """(errors, converged, seconds): the level's errors against its references at depths k and k - 1."""
        begin, chain, previous = time.perf_counter(), [], u_h
        for depth in range(1, self.depth + 1):
            finer = finer_domain(self.cfg, index, domain, depth, chain[-1][0] if chain else domain)
            u_ref = fem.Function(problem_of(self.cfg).space(self.cfg, finer.mesh), name="u_ref")
            outcome = solve(self.cfg, finer, u_ref, self.eps_for(level_eps, finer), previous)
            if not outcome.converged:
                logger.warning("reference of level %d at depth %d did not converge: %s", index, depth,
                               outcome.reason)
                return {}, False, self._seconds(begin)
            chain.append((finer, u_ref))
            previous = u_ref
        found = self.errors(u_h, chain[-1], level_eps, with_contact)
        coarser = chain[-2][1] if len(chain) > 1 else u_h
        found.update({f"ref_err_{name}": value for name, value in
                      measure.difference_norms(transfer(coarser, chain[-1][1].function_space), chain[-1][1]).items()})
        if len(chain) > 1:
            found.update({f"{name}_ref_shallow": value for name, value in
                          measure.difference_norms(transfer(u_h, chain[-2][1].function_space), chain[-2][1]).items()})
        return found, True, self._seconds(begin)

    def _seconds(self, begin):
        return self.comm.allreduce(time.perf_counter() - begin, op=MPI.MAX)

    def errors(self, u_h, reference, eps_value, with_contact):
        """{'L2_ref', 'H1_ref'} and, with_contact, the Γ_C errors (suffix _ref) of u_h against the
        reference (domain, u_ref) at eps_value (the level's eps: its energy-type error's scaling)."""
        domain, u_ref = reference
        moved = transfer(u_h, u_ref.function_space)
        found = measure.difference_norms(moved, u_ref)
        if with_contact:
            dofs, points = measure.contact_facet_dofs(u_ref.function_space, domain.facet_tags, CONTACT)
            found.update(measure.contact_errors(domain.mesh.comm, points[:, :domain.mesh.topology.dim],
                                                moved.x.array[dofs], u_ref.x.array[dofs], eps_value,
                                                self.cfg.alpha, found["H1"]))
        return {f"{name}_ref": value for name, value in found.items()}


def finer_domain(cfg, index, domain, depth, previous):
    """Level `index` (its Domain `domain`) refined `depth` times: the built-in grids and gmsh/file
    families of refine: uniform build it as the family would (the same mesh a finer level has), other
    meshes refine `previous` (the depth - 1 mesh) once more."""
    entry = cfg.mesh.levels[index]
    if cfg.mesh.kind in MESH_KINDS:
        return meshes.build(cfg.mesh, cfg.contact, entry * 2**depth, domain.mesh.comm)
    if cfg.mesh.refine == "uniform":
        return meshes.build(cfg.mesh, cfg.contact, entry + depth, domain.mesh.comm)
    return refinement.refine(previous)


def solve(cfg, domain, u, eps_value, previous):
    """The level's problem with eps = eps_value on the reference mesh, solved into u by the study's
    strategy from `previous` (a level's u_h: the nested guess); u = 0 on Γ_D (data-only scenes)."""
    eps = fem.Constant(domain.mesh, eps_value)
    problem_module = problem_of(cfg)
    forms = problem_module.forms(cfg, domain, u, eps)
    bcs = [problem_module.dirichlet_condition(u.function_space, domain, None)]
    problem = strategies.problem(forms, u, bcs, eps, eps_value, cfg.dimension)
    # the linear floor times the level's own solve, not its reference's
    return strategies.solve(dataclasses.replace(cfg.solver, linear_floor=False), problem, previous)


def successive_differences(u_coarse, u_fine):
    """{'diff_L2', 'diff_H1'}: ||u_h - u_{h/2}|| with the coarser solution moved onto the finer mesh
    (exact for nested meshes): rates that need no reference solution."""
    moved = transfer(u_coarse, u_fine.function_space)
    return {f"diff_{name}": value for name, value in measure.difference_norms(moved, u_fine).items()}
