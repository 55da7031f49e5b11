"""docs/results-format.md from the writer: the file list, study.h5's format as record/h5.py describes it,
and the outline of a study.h5 written by a fresh two-level study, read from the attributes it carries.
Usage: python scripts/results_format_page.py > docs/results-format.md (make results-format)."""
import sys
import tempfile
from pathlib import Path

import provenance
import signorini_cli
from signorini_cli import config
from signorini_cli.record import h5

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "demo.yaml"
FILES = """| file | written | content |
|---|---|---|
| `rates.csv` | after every level (atomically) | the rate table, one row per level (its first columns below) |
| `study.h5` | after every solve (atomically) | every table, per-level details and the record of the run (below) |
| `summary.csv` | after every level (atomically) | per norm: fitted and proven rate, verdict (refinement and signorini studies) |
| `work_precision.csv` | after every level (atomically) | error against cost, one row per error norm and level |
| `sweep.csv`, `fitted.csv`, `reference.csv` | after every solve of an `epsilon_sweep` | the model error per (mesh, α, ε), its fitted slope in ε, the Signorini solutions' rate table |
| `total.csv`, `<sub-study>/` | after every solve of a `total_error` study | per sub-study its finest errors and rates; each sub-study's own record in its folder |
| `status.txt` | at the start, after every solve and when the study ends (atomically) | one line: `running (k of n levels done)`, `complete`, `interrupted at level k` or `failed at level k: reason` |
| `<table>.md`, `<table>.tex` | at the end of `run`, and by `signorini report` | every table the study type reports (`rates`, `sweep`, `fitted`, `reference`, `total`), for notebooks and papers |
| `verdict.tex` | at the end of `run` | the verdict of a refinement or signorini study, a LaTeX float |
| `convergence`, `work_precision`, `newton`, `model_error`, `compare_*` `.png` / `.pdf` | at the end of `run` when `output.plots: true`, and by `signorini report` | the study type's figures |
| `fields/level_NN.xdmf` (+ `.h5`) | after each level when `output.fields: true` | u_h, its error and the contact indicator for ParaView |

Because the tables and `study.h5` are replaced after every solve, a study that was stopped holds every solve
it finished; `signorini report results/<study>` turns them into tables and figures without recomputing, and
`signorini run CONFIG --resume` computes the levels of a refinement study it did not finish (the config must
be unchanged, and every level group up to the last must be there whole)."""
EXAMPLE = r"""```python
import h5py
import yaml

with h5py.File("results/demo/study.h5", "r") as h5:
    print(h5.attrs["study"], "on", h5.attrs["mpi_size"], "rank(s), dolfinx", h5.attrs["version_dolfinx"])
    config = yaml.safe_load(h5.attrs["config_resolved"])
    print("alpha =", config["alpha"], " eps law:", config["epsilon"]["law"])
    table = h5["table"]
    for k in range(h5.attrs["levels_done"]):
        level = h5[f"level_{k:02d}"]
        steps = len(level["residuals"]) - 1
        print(level.attrs["N"], table["h"][k], table["L2"][k], table["rate_L2"][k], steps, "Newton steps")
```"""
AFTER = r"""## rates.md and rates.tex

The rate table in the deal.II `ConvergenceTable` style: N, h, DoFs, ε, Newton iterations, then for each norm
its error and its rate. Errors, h and ε in scientific notation with `output.digits` digits after the point
(`signorini report --digits` overrides), rates with two decimals, `–`/`--` where undefined. `rates.tex` is one
`table` float with a `\label` for `\usepackage{booktabs}`, numbers as `$m\times10^{k}$`, norms written out as
its headers, the columns its caption fixes (h = c/N, ε = c h^q, a value the same on every level) left out, split
by norms where it would pass `\textwidth`; levels that did not converge are marked `(failed)` and listed in the
caption. `verdict.tex` (at the end of `run`) is the verdict as a float of its own: per norm the observed rate
with its interval, the proven rate, the class and the paper's result.

## Fields (output.fields: true)

`fields/level_NN.xdmf` with its `level_NN.h5`, written through `dolfinx.io.XDMFFile` by all ranks: the mesh,
its boundary facet tags `boundary` (1 = Γ_C, 2 = Γ_D), and three P1 nodal functions: `u_h`; `error` =
u_h − u_ex at the nodes (manufactured scenes only); `contact` = 1 at the Γ_C nodes where u_h > 0 (the discrete
contact set, where the compliance term acts), 0 elsewhere. Open the `.xdmf` in ParaView (XDMF3 reader)."""


def example_run():
    """(provenance line, outline table) of the study.h5 a two-level run of configs/demo.yaml writes."""
    with tempfile.TemporaryDirectory() as out:
        study = signorini_cli.run(config.load(CONFIG, [f"output.dir={out}", "mesh.refinements=[4, 8]"]), write=True)
        if not study.converged:
            raise SystemExit(f"{CONFIG}: a level did not converge")
        folder = study.config.output_dir
        made, rows = provenance.line("results-format", [folder]), h5.outline(folder / h5.NAME)
    return made, ["| path | type, length | units | description |", "|---|---|---|---|"] + [
        f"| `{name}` | {kind} | {units or '–'} | {what} |" for name, kind, units, what in rows]


def page():
    made, outline = example_run()
    lines = ["# Results format", "", made + " The study.h5 part is written "
             "from the descriptions the writer stores in every file (`signorini_cli/record/h5.py`).", "",
             "A study writes into `<output.dir>/<study>/` (default `results/<study>/`):", "", FILES, "",
             "## study.h5", "",
             "HDF5, written by rank 0 with h5py. Every dataset and every group with attributes carries `units` "
             "and a one-line `description`: `h5dump -A study.h5` alone explains the file.", "",
             h5.describe(), "### An example", "",
             "The outline of the study.h5 that `signorini run configs/demo.yaml --set mesh.refinements=[4,8]` "
             "writes, read back from its own attributes (the row's attributes of the level groups are left out):",
             ""] + outline + ["", "### Reading a study back", "",
                                         "The example below is run by the test suite (`tests/scripts/test_docs.py`) on a fresh study:",
                                         "", EXAMPLE, "", AFTER]
    return "\n".join(lines).rstrip("\n") + "\n"


if __name__ == "__main__":
    sys.stdout.write(page())
