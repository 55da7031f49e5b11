"""solver.petsc_options checked before any solve: scalar values of the right type for the options the
study's SNES, KSP and PC read, and no option that would replace the study's own success test."""
import math
import re

# option -> its config key: these would let PETSc, not the study's success test (solver.SuccessTest),
# decide convergence (a linear-only or test-free SNES reports "converged" for any iterate), or set what
# a config key already sets and the success test reads
OWNED = {"snes_convergence_test": "solver.rtol, solver.atol and solver.stol",
         "snes_rtol": "solver.rtol", "snes_atol": "solver.atol", "snes_stol": "solver.stol"}

# the value types of the options the study's objects read (PETSc's manual pages: SNESSetFromOptions,
# KSPSetFromOptions, PCSetFromOptions, PCHYPRE, PCGAMG, SNESLineSearchSetFromOptions)
INTEGER = ("snes_max_it", "snes_max_funcs", "snes_max_fail", "snes_max_linear_solve_fail",
           "snes_lag_preconditioner", "snes_lag_jacobian", "snes_linesearch_max_it", "ksp_max_it",
           "ksp_gmres_restart", "pc_factor_levels", "pc_hypre_boomeramg_max_levels",
           "pc_hypre_boomeramg_max_iter", "pc_hypre_boomeramg_agg_nl", "pc_hypre_boomeramg_agg_num_paths",
           "pc_gamg_agg_nsmooths",
           "pc_mg_levels", "mat_mumps_icntl_\\d+")
REAL = ("snes_divergence_tolerance", "snes_tr_delta0", "snes_linesearch_damping", "snes_linesearch_minlambda",
        "snes_linesearch_maxstep", "ksp_rtol", "ksp_atol", "ksp_divtol", "pc_factor_shift_amount",
        "pc_hypre_boomeramg_strong_threshold", "pc_hypre_boomeramg_truncfactor", "pc_gamg_threshold",
        "mat_mumps_cntl_\\d+")
FLAG = ("snes_ksp_ew", "snes_mf", "snes_mf_operator", "snes_fd", "ksp_error_if_not_converged")
# monitors and views: no value, or a viewer "type[:file[:format]]" (PetscOptionsGetViewer; another value
# is a PETSc error inside the solve)
VIEWER = (r"\w+_monitor(_\w+)?", r"\w+_view(_\w+)?", r"\w+_converged_reason")
VIEWER_TYPES = ("ascii", "binary", "draw", "socket", "vtk", "hdf5", "matlab", "saws", "glvis", "adios",
                "exodusii", "vu", "mathematica")
BOOLEANS = ("", "1", "0", "true", "false", "yes", "no", "on", "off")
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


class OptionError(ValueError):
    """A bad option: `name` is its name, the message says what is wrong."""

    def __init__(self, name, message):
        self.name = name
        super().__init__(message)


def check(name, value):
    """(name, value as PETSc reads it) for one option, or OptionError."""
    if not NAME.match(name):
        raise OptionError(name, "is not a PETSc option name (letters, digits and _)")
    if isinstance(value, (dict, list)):
        raise OptionError(name, f"must be a single value, not a {'mapping' if isinstance(value, dict) else 'list'}")
    text = "" if value is None else str(value).lower() if isinstance(value, bool) else str(value)
    if name in OWNED:
        raise OptionError(name, f"would replace the study's success test; set {OWNED[name]} instead")
    if name == "snes_type":  # ksponly, or newtonls in place of the Signorini VI's vinewtonrsls
        raise OptionError(name, "the study chooses the SNES type its success test checks; set solver.method "
                                "(newtonls | newtontr) instead")
    _check_type(name, text)
    return name, text


def _check_type(name, text):
    kind = _kind(name)
    if kind == "integer" and not re.fullmatch(r"[-+]?\d+", text.strip()):
        raise OptionError(name, f"must be an integer, got {text!r}")
    if kind == "real" and not _is_real(text):
        raise OptionError(name, f"must be a finite number, got {text!r}")
    if kind == "flag" and text.strip().lower() not in BOOLEANS:
        raise OptionError(name, f"takes no value or true/false, got {text!r}")
    if kind == "viewer" and text and text.split(":")[0] not in VIEWER_TYPES:
        raise OptionError(name, f"takes no value or a viewer ({', '.join(VIEWER_TYPES[:3])}, ...[:file]), "
                                f"got {text!r}")


def _kind(name):
    for kind, names in (("integer", INTEGER), ("real", REAL), ("flag", FLAG), ("viewer", VIEWER)):
        if any(re.fullmatch(pattern, name) for pattern in names):
            return kind
    return None


def _is_real(text):
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False
