"""The total error: refinement studies with ε = θ h^p beside the VI, side by side (docs/limit.md); each
sub-study is recorded as a study of its own, the total table and a comparison figure beside them."""
import dataclasses
from dataclasses import dataclass

from mpi4py import MPI

from .. import config
from ..analysis import rates
from . import refinement, signorini
from .level import NORMS, Figure, Table, rate_table

NAME = "total_error"
UNIT = "solves"
RESUMABLE = False
POINTS = False  # a study of its own levels or solves (a map: points, run and recorded by app/maps)
PARTS = "studies/"  # the tables of the sub-studies, in study.h5 only: each has its rates.csv in its folder


@dataclass
class Total:
    """A total-error study: sub-study name -> (config, levels); iterating gives every level."""
    studies: dict

    def __iter__(self):
        return (level for _, levels in self.studies.values() for level in levels)


def run(cfg, on_level=None, comm=MPI.COMM_WORLD, monitor=None, done=()):
    """A refinement study with ε = θ h^p for every α and p, and the same study by the VI, side by side."""
    total = Total({})
    for name, sub in sub_studies(cfg):
        levels = []
        total.studies[name] = (sub, levels)

        def record(found, levels=levels):
            levels[:] = found
            if on_level is not None:
                on_level(total)

        SUB_STUDIES[sub.study_type].run(sub, on_level=record, comm=comm)
    return total


SUB_STUDIES = {module.NAME: module for module in (refinement, signorini)}


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


def tables(cfg, total):
    """total, and every sub-study's rate table as studies/<name> (in study.h5 only: the sub-study's
    folder has its rates.csv); none before the first solve."""
    if isinstance(total, list):
        return {}
    named = {"total": total_table(total, cfg.limit.fit_last)}
    named.update({f"{PARTS}{name}": rate_table(levels) for name, (_, levels) in total.studies.items()})
    return named


def summary(cfg, total):
    """No verdict of its own: the paper proves no total-error rate (docs/limit.md)."""
    return None


def levels_of(total):
    return []


def parts(cfg, total):
    """(config, levels) of every sub-study with a level: each is written as a study in its own folder."""
    if isinstance(total, list):
        return []
    return [(sub, levels) for sub, levels in total.studies.values() if levels]


def reported(cfg, named):
    """The total table; every sub-study's rate table and figures in its folder; all sub-studies' errors
    against h side by side."""
    studies = compared(named)
    shown = [Table("total", named["total"])] + [Table(f"{name}/rates", rows, paper=True, terminal=False)
                                                for name, rows in studies.items()]
    figures = [Figure(f"{name}/convergence", "convergence", rows) for name, rows in studies.items()]
    return shown, figures + ([Figure("total_error", "comparison", studies)] if studies else [])


def compared(named):
    """What `compare` overlays, and the figure of a study: every sub-study's rate table by its name."""
    return {key[len(PARTS):]: rows for key, rows in named.items() if key.startswith(PARTS) and rows}


def title(cfg, name):
    return f"{name}: d = {cfg.dimension}, total error against u_S"


def total_table(total, last):
    """One row per sub-study: its finest level's errors against u_S, the last and the fitted rates."""
    rows = []
    for name, (sub, levels) in total.studies.items():
        finest = rate_table(levels)[-1] if levels else {}
        vi_study = sub.study_type == signorini.NAME
        row = {"study": name, "solver": "signorini" if vi_study else "compliance",
               "alpha": None if vi_study else sub.alpha, "p": None if vi_study else sub.epsilon.exponent,
               "levels": len(levels), "N": finest.get("N"), "h": finest.get("h"), "epsilon": finest.get("epsilon"),
               "converged": all(lv.outcome.converged for lv in levels)}
        for norm in NORMS:
            row[norm] = finest.get(norm)
            row[f"rate_{norm}"] = finest.get(f"rate_{norm}")
            row[f"fit_{norm}"] = rates.fitted([lv.h for lv in levels], [lv.errors.get(norm) for lv in levels],
                                              [lv.outcome.converged for lv in levels], last)
        rows.append(row)
    return rows
