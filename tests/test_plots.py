"""Figures: written headless (Agg, no pyplot), triangles labelled with proven or fitted rates, overlays."""
import subprocess
import sys

import numpy as np
import yaml

from signorini_cli import plots
from conftest import BASE, merge

H = [0.2, 0.1, 0.05, 0.025]


def synthetic(slopes, failed=(), h=H):
    """Rows of a study whose norm X has error h^slope exactly; levels in `failed` did not converge."""
    rows = []
    for k, h_k in enumerate(h):
        ok = k not in failed
        row = {"level": k, "N": 2 ** (k + 3), "h": h_k, "dofs": 4 ** (k + 3), "epsilon": h_k,
               "converged": ok, "newton_its": 4 + k, "time_s": 0.1 * 4 ** k, "reason": "R"}
        for norm, slope in slopes.items():
            row[norm] = h_k ** slope if ok else None
            row[f"rate_{norm}"] = slope if ok and k > 0 else None
        rows.append(row)
    return rows


def test_write_all_headless_png_pdf(tmp_path):
    import matplotlib
    before = dict(matplotlib.rcParams)
    paths = plots.write_all(synthetic({"L2": 2.0, "H1": 1.0}), tmp_path, title="t")
    names = sorted(p.name for p in paths)
    assert names == sorted(f"{n}.{ext}" for n in ("convergence", "work_precision", "newton")
                           for ext in ("png", "pdf"))
    for path in paths:
        magic = b"\x89PNG" if path.suffix == ".png" else b"%PDF"
        assert path.read_bytes().startswith(magic)
    assert "matplotlib.pyplot" not in sys.modules  # Figure + Agg canvas: no GUI backend, no pyplot state
    assert dict(matplotlib.rcParams) == before  # the style stays inside plots.styled()


def triangle_labels(ax):
    """The texts of the slope triangles: "1" under each horizontal leg, the rate beside each vertical one."""
    return sorted(text.get_text() for text in ax.texts)


def test_triangles_show_proven_rate_else_fitted():
    rows = synthetic({"L2": 1.9, "H1": 0.97})
    with plots.styled():
        fig = plots.convergence(rows, proven={"L2": 2.0})
    (ax,) = fig.axes
    assert triangle_labels(ax) == ["0.97", "1", "1", "2"]  # L2: proven 2; H1: not given, its fitted slope
    assert "proven rate, else slope fitted" in ax.get_legend().get_title().get_text()
    assert any("fitted slope 1.90" in t.get_text() for t in ax.get_legend().get_texts())


def test_many_norms_get_one_panel_each():
    rows = synthetic({"L2": 2.0, "H1": 1.0, "L2_gamma_c": 1.5})
    with plots.styled():
        fig = plots.convergence(rows)
    assert len(fig.axes) == 3
    assert [triangle_labels(ax) for ax in fig.axes] == [["1", "2"], ["1", "1"], ["1", "1.5"]]


def test_failed_level_left_out_of_curves_marked_in_newton():
    rows = synthetic({"L2": 2.0}, failed=(2,))
    h, e = plots.error_curves(rows)["L2"]
    assert list(h) == [0.2, 0.1, 0.025]
    with plots.styled():
        fig = plots.newton({"": rows})
    crosses = [line for line in fig.axes[0].lines if line.get_marker() == "x"]
    assert len(crosses) == 1 and list(crosses[0].get_xdata()) == [rows[2]["dofs"]]


def test_work_precision_cumulative_includes_failed_levels():
    rows = synthetic({"L2": 2.0}, failed=(1,))
    with plots.styled():
        fig = plots.work_precision(rows)
    cumulative, own = (ax.lines[0].get_xdata() for ax in fig.axes)
    times = [row["time_s"] for row in rows]
    assert np.allclose(cumulative, np.cumsum(times)[[0, 2, 3]])  # the failed level's time still counts
    assert np.allclose(own, [times[k] for k in (0, 2, 3)])


def test_compare_overlays_every_study(tmp_path):
    studies = {"a": synthetic({"L2": 2.0, "H1": 1.0}), "b": synthetic({"L2": 1.5})}
    paths = plots.write_comparison(studies, tmp_path)
    assert {p.stem for p in paths} == {"compare_convergence", "compare_work_precision", "compare_newton"}
    with plots.styled():
        fig = plots.compare_convergence(studies)
    assert [len(ax.lines) for ax in fig.axes] == [2, 1]  # L2: a and b; H1: a only


def test_single_level_study_plots_without_triangles(tmp_path):
    rows = synthetic({"L2": 2.0}, h=H[:1])
    with plots.styled():
        fig = plots.convergence(rows)
    assert triangle_labels(fig.axes[0]) == []
    assert plots.write_all(rows, tmp_path)


def test_run_without_plots_never_imports_matplotlib(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(merge(BASE, {"output": {"dir": str(tmp_path), "plots": False}})))
    code = ("import sys; from signorini_cli import cli; code = cli.main(['run', sys.argv[1], '--quiet']); "
            "assert 'matplotlib' not in sys.modules, 'matplotlib imported'; sys.exit(code)")
    done = subprocess.run([sys.executable, "-c", code, str(cfg)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "t" / "rates.tex").exists() and not list((tmp_path / "t").glob("*.png"))
