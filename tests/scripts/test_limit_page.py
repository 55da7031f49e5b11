"""docs/limit.md is written from runs: every section, the plot (headless), nothing typed in."""
import yaml

import runpy
import sys
from pathlib import Path

from signorini_cli.app import cli
from conftest import BASE, U_SIGNORINI, merge

SIGNORINI = {"alpha": None, "epsilon": None, "problem": {"exact": U_SIGNORINI, "exact_solves": "signorini"},
             "output": {"plots": False}}  # the studies' own figures: not the page's business, and slow
STUDIES = {
    "vi": {"study_type": "signorini", "mesh": {"refinements": [4, 8]}},
    "sweep": {"study_type": "epsilon_sweep", "mesh": {"refinements": [8]},
              "limit": {"alpha": [1, 2], "epsilon": [1e-2, 1e-3, 1e-4]}},
    "total": {"study_type": "total_error", "mesh": {"refinements": [4, 8]},
              "limit": {"alpha": [2], "exponent": [1]}},
}


SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
sys.path.insert(0, str(SCRIPTS))  # the page generators share scripts/provenance.py
limit_page = runpy.run_path(str(SCRIPTS / "limit_page.py"))


def test_page_from_small_runs(tmp_path):
    paths = []
    for name, changes in STUDIES.items():
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump(merge(BASE, dict(SIGNORINI, study=name, **changes))))
        assert cli.main(["run", str(path), "--output", str(tmp_path / "results")]) == cli.EXIT_OK
        paths.append(str(path))
    out = tmp_path / "docs" / "limit.md"
    assert limit_page["main"](paths + ["--output", str(tmp_path / "results"), "--out", str(out)]) == 0
    page = out.read_text()
    for heading in ("## 1. The discrete Signorini problem", "## 2. The model error", "## 3. The total error"):
        assert heading in page
    assert "| alpha2-p1 | 2 | 1 |" in page and "| signorini | – | – |" in page
    assert "Decreasing at every step for every α, mesh and measure: yes" in page
    assert (out.parent / limit_page["PLOT"]).stat().st_size > 10_000  # a rendered PNG, through Agg
