"""solver.petsc_options checked before any solve: names matched as PETSc matches them (case-insensitively,
with or without the study's prefix), values of the right type, range and name for the options the study's
SNES, KSP and PC read, and no option that would replace the study's own success test."""
import math
import re

# option -> its config key: these would let PETSc, not the study's success test (solver.SuccessTest),
# decide convergence (a linear-only or test-free SNES reports "converged" for any iterate), or set what
# a config key already sets and the success test reads
OWNED = {"snes_convergence_test": "solver.rtol, solver.atol and solver.stol",
         "snes_rtol": "solver.rtol", "snes_atol": "solver.atol", "snes_stol": "solver.stol"}
# these turn a failed solve, which the study reports as a level that did not converge, into a PETSc error
ERRORS = ("ksp_error_if_not_converged", "snes_error_if_not_converged", "pc_factor_mat_error_if_not_converged")

# the value types of the options the study's objects read (PETSc's manual pages: SNESSetFromOptions,
# KSPSetFromOptions, PCSetFromOptions, PCHYPRE, PCGAMG, SNESLineSearchSetFromOptions), with the smallest
# value PETSc takes (SNESSetFromOptions: a lag of -1 from the options is an error, -2 is "once")
INTEGER = {"snes_max_it": 0, "snes_max_funcs": -1, "snes_max_fail": 0, "snes_max_linear_solve_fail": 0,
           "snes_lag_preconditioner": "lag", "snes_lag_jacobian": "lag", "snes_linesearch_max_it": 1,
           "ksp_max_it": 0, "ksp_gmres_restart": 1, "pc_factor_levels": 0, "pc_hypre_boomeramg_max_levels": 2,
           "pc_hypre_boomeramg_max_iter": 1, "pc_hypre_boomeramg_agg_nl": 0,
           "pc_hypre_boomeramg_agg_num_paths": 1, "pc_gamg_agg_nsmooths": 0, "pc_mg_levels": 1,
           "ksp_richardson_self_scale": None, "mat_mumps_icntl_\\d+": None}
# real -> (lowest, highest, whether the lowest is allowed) as PETSc checks them when the solver is set up
REAL = {"snes_divergence_tolerance": None, "snes_tr_delta0": (0.0, None, False),
        "snes_linesearch_damping": (0.0, None, False), "snes_linesearch_minlambda": (0.0, None, False),
        "snes_linesearch_maxstep": (0.0, None, False), "ksp_rtol": (0.0, 1.0, True), "ksp_atol": (0.0, None, True),
        "ksp_divtol": None, "ksp_richardson_scale": None, "pc_factor_shift_amount": (0.0, None, True),
        "pc_hypre_boomeramg_strong_threshold": (0.0, 1.0, True), "pc_hypre_boomeramg_truncfactor": (0.0, 1.0, True),
        "pc_gamg_threshold": None, "pc_jacobi_fixdiagonal": None, "mat_mumps_cntl_\\d+": None}
# PETSc's own names of the types these options choose (petsc4py: PETSc.KSP.Type, PETSc.PC.Type,
# PETSc.Mat.SolverType, PETSc.PC.GAMGType, PCHYPRE's -pc_hypre_type; tests/config/test_config.py compares
# them with the installed petsc4py's): another value is a PETSc error inside the first solve
KSP_TYPES = ("bcgs", "bcgsl", "bicg", "cg", "cgls", "cgne", "cgs", "chebyshev", "cr", "dgmres", "fbcgs", "fbcgsr",
             "fcg", "fetidp", "fgmres", "gcr", "gltr", "gmres", "groppcg", "hpddm", "ibcgs", "lcd", "lgmres", "lsqr",
             "minres", "nash", "none", "pgmres", "pipebcgs", "pipecg", "pipecg2", "pipecgrr", "pipecr", "pipefcg",
             "pipefgmres", "pipegcr", "pipelcg", "pipeprcg", "preonly", "python", "qcg", "qmrcgs", "richardson",
             "stcg", "symmlq", "tcqmr", "tfqmr", "tsirm")
PC_TYPES = ("asm", "bddc", "bfbt", "bjacobi", "cholesky", "chowiluviennacl", "composite", "cp", "deflation",
            "eisenstat", "exotic", "fieldsplit", "galerkin", "gamg", "gasm", "h2opus", "hmg", "hpddm", "hypre", "icc",
            "ilu", "jacobi", "kaczmarz", "ksp", "lmvm", "lsc", "lu", "mat", "mg", "ml", "nn", "none", "parms",
            "patch", "pbjacobi", "pfmg", "python", "qr", "redistribute", "redundant", "rowscalingviennacl",
            "saviennacl", "shell", "sor", "spai", "svd", "syspfmg", "telescope", "tfs", "vpbjacobi")
SOLVER_TYPES = ("bas", "cholmod", "cuda", "cusparse", "elemental", "essl", "klu", "lusol", "matlab", "mkl_cpardiso",
                "mkl_pardiso", "mumps", "pastix", "petsc", "scalapack", "sparseelemental", "spqr", "strumpack",
                "superlu", "superlu_dist", "umfpack")
CHOICE = {"ksp_type": KSP_TYPES, "pc_type": PC_TYPES, "pc_factor_mat_solver_type": SOLVER_TYPES,
          "snes_linesearch_type": ("basic", "bt", "cp", "l2", "nleqerr", "shell"),
          "pc_hypre_type": ("boomeramg", "pilut", "parasails", "euclid", "ams", "ads"),
          "pc_gamg_type": ("agg", "classical", "geo"),
          "ksp_norm_type": ("default", "none", "preconditioned", "unpreconditioned", "natural")}
FLAG = ("snes_ksp_ew", "snes_mf", "snes_mf_operator", "snes_fd")
# monitors and views: no value, or a viewer "type[:file[:format]]" (PetscOptionsGetViewer; another value
# is a PETSc error inside the solve)
VIEWER = (r"\w+_monitor(_\w+)?", r"\w+_view(_\w+)?", r"\w+_converged_reason")
VIEWER_TYPES = ("ascii", "binary", "draw", "socket", "vtk", "hdf5", "matlab", "saws", "glvis", "adios",
                "exodusii", "vu", "mathematica")
BOOLEANS = ("", "1", "0", "true", "false", "yes", "no", "on", "off")
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
PREFIX = re.compile(r"^signorini_(\d+_)?")  # the study's own prefix (solver.NewtonSolver), which PETSc adds


class OptionError(ValueError):
    """A bad option: `name` is its name, the message says what is wrong."""

    def __init__(self, name, message):
        self.name = name
        super().__init__(message)


def canonical(name):
    """The option as PETSc reads it under the study's prefix: case-insensitive, without a leading - and
    without the prefix (`-Signorini_0_SNES_TYPE` is snes_type)."""
    return PREFIX.sub("", str(name).lstrip("-").lower())


def check(name, value):
    """(name as PETSc matches it, value as PETSc reads it) for one option, or OptionError."""
    if not NAME.match(str(name).lstrip("-")):
        raise OptionError(name, "is not a PETSc option name (letters, digits and _)")
    if isinstance(value, (dict, list)):
        raise OptionError(name, f"must be a single value, not a {'mapping' if isinstance(value, dict) else 'list'}")
    text = "" if value is None else str(value).lower() if isinstance(value, bool) else str(value)
    key = canonical(name)
    if key in OWNED:
        raise OptionError(name, f"would replace the study's success test; set {OWNED[key]} instead")
    if key == "snes_type":  # ksponly, or newtonls in place of the Signorini VI's vinewtonrsls
        raise OptionError(name, "the study chooses the SNES type its success test checks; set solver.method "
                                "(newtonls | newtontr) instead")
    if key in ERRORS:
        raise OptionError(name, "would end the study with a PETSc error where a failed solve is a level that "
                                "did not converge (or a fallback to a direct solve)")
    _check_type(name, key, text)
    return key, text


def _check_type(name, key, text):
    kind, rule = _kind(key)
    if kind == "integer":
        _check_integer(name, text, rule)
    if kind == "real":
        _check_real(name, text, rule)
    if kind == "choice" and text not in rule:
        raise OptionError(name, f"{text!r} is not a PETSc {key.replace('_', ' ')} ({', '.join(rule[:12])}"
                                f"{', ...' if len(rule) > 12 else ''})")
    if kind == "flag" and text.strip().lower() not in BOOLEANS:
        raise OptionError(name, f"takes no value or true/false, got {text!r}")
    if kind == "viewer" and text and text.split(":")[0] not in VIEWER_TYPES:
        raise OptionError(name, f"takes no value or a viewer ({', '.join(VIEWER_TYPES[:3])}, ...[:file]), "
                                f"got {text!r}")


def _check_integer(name, text, low):
    if not re.fullmatch(r"[-+]?\d+", text.strip()):
        raise OptionError(name, f"must be an integer, got {text!r}")
    value = int(text)
    if low == "lag" and not (value >= 1 or value == -2):
        raise OptionError(name, f"must be >= 1 (every that many Newton steps) or -2 (once), got {value}")
    if isinstance(low, int) and value < low:
        raise OptionError(name, f"must be >= {low}, got {value}")


def _check_real(name, text, bounds):
    if not _is_real(text):
        raise OptionError(name, f"must be a finite number, got {text!r}")
    if bounds is None:
        return
    value, (low, high, closed) = float(text), bounds
    if value < low or (value == low and not closed) or (high is not None and value >= high):
        interval = f"{'[' if closed else '('}{low:g}, {high:g})" if high is not None else \
            f"{'>=' if closed else '>'} {low:g}"
        raise OptionError(name, f"must be {'in ' if high is not None else ''}{interval}, got {text}")


def _kind(key):
    for kind, table in (("integer", INTEGER), ("real", REAL)):
        for pattern, rule in table.items():
            if re.fullmatch(pattern, key):
                return kind, rule
    if key in CHOICE:
        return "choice", CHOICE[key]
    if key in FLAG:
        return "flag", None
    if any(re.fullmatch(pattern, key) for pattern in VIEWER):
        return "viewer", None
    return None, None


def _is_real(text):
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False
