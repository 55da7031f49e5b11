"""signorini: convergence studies for the normal compliance model of the Signorini problem.

`from signorini_cli import load, run` is the Python API (docs/api.md); it is imported on first use, so
that `signorini --version` loads neither dolfinx nor PETSc."""
__version__ = "0.1.0"
API = ("load", "run")


def __getattr__(name):
    """load and run from app/api.py, imported when first asked for."""
    if name in API:
        from .app import api
        return getattr(api, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
