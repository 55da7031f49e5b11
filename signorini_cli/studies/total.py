"""The total error: refinement studies with ε = θ h^p beside the VI, side by side (docs/limit.md)."""
import dataclasses
from dataclasses import dataclass

from mpi4py import MPI

from .. import config
from .refinement import run_refinement
from .signorini import run_signorini


@dataclass
class Total:
    """A total-error study: sub-study name -> (config, levels); iterating gives every level."""
    studies: dict

    def __iter__(self):
        return (level for _, levels in self.studies.values() for level in levels)


def run_total(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """A refinement study with ε = θ h^p for every α and p, and the same study by the VI, side by side."""
    total = Total({})
    for name, sub in sub_studies(cfg):
        levels = []
        total.studies[name] = (sub, levels)

        def record(found, levels=levels):
            levels[:] = found
            if on_level is not None:
                on_level(total)

        SUB_STUDIES[sub.study_type](sub, on_level=record, comm=comm)
    return total


SUB_STUDIES = {"refinement": run_refinement, "signorini": run_signorini}


def sub_studies(cfg):
    """(name, config) of every sub-study of a total-error study: alpha<α>-p<p> and signorini (the VI)."""
    subs = []
    for alpha in cfg.limit.alpha:
        for p in cfg.limit.exponent:
            name = f"alpha{alpha:g}-p{p:g}"
            epsilon = config.Epsilon.power(cfg.limit.theta, p)
            subs.append((name, _sub_study(cfg, name, "refinement", alpha=alpha, epsilon=epsilon)))
    subs.append(("signorini", _sub_study(cfg, "signorini", "signorini")))
    return subs


def _sub_study(cfg, name, study_type, **changes):
    """A plain study of its own type, written to <output>/<study>/<name>/."""
    output = dataclasses.replace(cfg.output, dir=str(cfg.output_dir))
    return dataclasses.replace(cfg, study=name, study_type=study_type, limit=None, output=output, **changes)
