"""Reference solutions for scenes given by their data only: the same problem solved on the mesh one or
two uniform refinements beyond the finest level, levels moved onto it by an exact (nested) transfer."""
import dataclasses
import logging
import time

from mpi4py import MPI

from dolfinx import fem

from ..meshing import meshes
from ..problems import measure
from ..problems.registry import problem_of
from ..solve import strategies
from ..solve.transfer import transfer

logger = logging.getLogger(__name__)


class Reference:
    """u_ref on the reference mesh, solved once per eps (reference_epsilon: per_level compares each
    level with u_ref at that level's eps; fixed with u_ref at the law's eps on the reference mesh)."""

    def __init__(self, cfg, comm=MPI.COMM_WORLD):
        self.cfg, self.comm = cfg, comm
        self.n = None  # the reference level's N, once built
        self.domain = None
        self.solutions = {}  # eps -> (u_ref, converged)

    def eps_for(self, level_eps):
        """The eps of the reference a level with eps = level_eps is compared with."""
        if self.cfg.verification.reference_epsilon == "per_level":
            return level_eps
        return self.cfg.epsilon(self.mesh().h)

    def mesh(self):
        """The reference level's Domain, built on first use."""
        if self.domain is None:
            self.domain, nested = meshes.reference_domain(self.cfg.mesh, self.cfg.contact,
                                                          self.cfg.verification.reference_refinements, self.comm)
            self.n = self.domain.n
            if not nested:
                logger.warning("reference N=%d: not every level is nested in it, the transfer to it "
                               "interpolates instead of being exact", self.n)
        return self.domain

    def solution(self, eps_value, start):
        """(u_ref, converged, seconds spent): solved at eps_value from `start` (a level's u_h) moved to
        the reference mesh, or taken from the cache."""
        if eps_value in self.solutions:
            return (*self.solutions[eps_value], 0.0)
        begin = time.perf_counter()
        domain = self.mesh()
        u_ref = fem.Function(problem_of(self.cfg).space(self.cfg, domain.mesh), name="u_ref")
        outcome = solve(self.cfg, domain, u_ref, eps_value, start)
        if not outcome.converged:
            logger.warning("reference N=%d at eps=%.3e did not converge: %s", self.n, eps_value, outcome.reason)
        self.solutions[eps_value] = (u_ref, outcome.converged)
        return u_ref, outcome.converged, self.comm.allreduce(time.perf_counter() - begin, op=MPI.MAX)

    def errors(self, u_h, u_ref, eps_value, with_contact):
        """{'L2_ref', 'H1_ref'} and, with_contact, the Γ_C errors (suffix _ref) of u_h against u_ref
        at eps_value (the level's eps: the eps its own energy-type error is scaled with)."""
        domain = self.mesh()
        moved = transfer(u_h, u_ref.function_space)
        found = measure.difference_norms(moved, u_ref)
        if with_contact:
            ds_c = domain.ds_c(measure.contact_error_degree(u_ref.function_space))
            found.update(measure.contact_errors(moved, u_ref, eps_value, self.cfg.alpha, ds_c, found["H1"]))
        return {f"{name}_ref": value for name, value in found.items()}


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
