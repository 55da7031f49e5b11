"""Figures: written headless (Agg, no pyplot), triangles labelled with proven or fitted rates, overlays."""
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.text import Text

from signorini_cli.report import plots
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
    had_pyplot = "matplotlib.pyplot" in sys.modules  # another test (the API page's notebook) may have loaded it
    paths = plots.write_all(synthetic({"L2": 2.0, "H1": 1.0}), tmp_path, title="t")
    names = sorted(p.name for p in paths)
    assert names == sorted(f"{n}.{ext}" for n in ("convergence", "work_precision", "newton")
                           for ext in ("png", "pdf"))
    for path in paths:
        magic = b"\x89PNG" if path.suffix == ".png" else b"%PDF"
        assert path.read_bytes().startswith(magic)
    # Figure + Agg canvas: no GUI backend, no pyplot state
    assert had_pyplot or "matplotlib.pyplot" not in sys.modules
    assert "import matplotlib.pyplot" not in Path(plots.__file__).read_text()
    assert dict(matplotlib.rcParams) == before  # the style stays inside plots.styled()


def triangle_labels(ax):
    """The texts of the slope triangles: "1" under each horizontal leg, the rate beside each vertical one."""
    return sorted(text.get_text() for text in ax.texts)


def test_triangles_proven_marked_apart_from_fitted():
    rows = synthetic({"L2": 1.9, "H1": 0.97})
    with plots.styled():
        fig = plots.convergence(rows, proven={"L2": 2.0})
    (ax,) = fig.axes
    assert triangle_labels(ax) == ["0.97", "1", "1", "2 proven"]  # L2: proven 2; H1: its fitted slope
    proven, fitted = ax.patches  # drawn in the norms' order: L2, H1
    assert proven.get_facecolor()[3] == 0 and proven.get_linestyle() != "solid"  # open, dashed
    assert fitted.get_facecolor()[3] > 0 and fitted.get_linestyle() == "-"  # filled, solid
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [r"$\|u-u_h\|_{L^2}$  (fit 1.90)",
                                                                     r"$|u-u_h|_{H^1}$  (fit 0.97)"]


def test_plot_slopes_read_fit_levels():
    # slope 2 on the coarse levels, 1 on the finest: 2 levels fit 1, all 4 fit the LSQ line through both
    rows = synthetic({"L2": 2.0})
    rows[-1]["L2"] = rows[-2]["L2"] * 0.5
    with plots.styled():
        two, four = (plots.convergence(rows, fit_levels=k) for k in (2, 4))
    assert two.axes[0].get_legend().get_texts()[0].get_text() == r"$\|u-u_h\|_{L^2}$  (fit 1.00)"
    assert four.axes[0].get_legend().get_texts()[0].get_text() != r"$\|u-u_h\|_{L^2}$  (fit 1.00)"


def test_figure_fit_is_the_verdicts_rate_also_with_a_log_factor(make_config):
    # alpha = 3 (a bound with |ln h|): the legend's fit and the verdict's rate are one slope, the plain one
    import math
    from signorini_cli.analysis import verdict
    from signorini_cli.solve.solver import Outcome
    from signorini_cli.studies import Level
    from signorini_cli.studies.level import rate_table
    outcome = Outcome(True, "CONVERGED_FNORM_ABS", 5, 5, (1.0,))
    levels = [Level(k, round(1 / h), h, 100, h, outcome, {"L2": h**2 * -math.log(h)}, 1.0) for k, h in enumerate(H)]
    (l2,) = verdict.summarize(make_config(alpha=3.0), levels).norms
    with plots.styled():
        fig = plots.convergence(rate_table(levels), {"L2": 2.0}, fit_levels=3)
    assert fig.axes[0].get_legend().get_texts()[0].get_text().endswith(f"(fit {l2.observed:.2f})")
    assert round(l2.observed, 2) != round(l2.log_corrected, 2)  # the other fit would show another number


def test_many_norms_two_per_panel_and_per_norm_figures(tmp_path):
    rows = synthetic({"L2": 2.0, "H1": 1.0, "L2_gamma_c": 1.5})
    with plots.styled():
        fig = plots.convergence(rows)
    assert [triangle_labels(ax) for ax in fig.axes] == [["1", "1", "1", "2"], ["1", "1.5"]]
    paths = plots.write_all(rows, tmp_path, per_norm=True)
    assert {p.stem for p in paths} >= {"convergence_L2", "convergence_H1", "convergence_L2_gamma_c"}


def page_checks(fig, width_pt):
    """The figure is width_pt wide, every text at least 8 pt, no legend overlapping an axes' data area."""
    assert fig.get_figwidth() * 72.27 == pytest.approx(width_pt)  # TeX points: \includegraphics at 100 %
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_text()]
    assert min(sizes) >= 8
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is not None and ax.axison:  # an axes switched off holds a figure's one legend
            box = legend.get_window_extent(renderer)
            assert not box.overlaps(ax.get_window_extent(renderer)), "legend on the data"


@pytest.mark.parametrize("width", [None, 510.0])
def test_figures_fit_a_page_text_8pt_legends_off_the_data(width):
    rows = synthetic({"L2": 2.0, "H1": 1.0, "pos_gc": 1.0, "energy_err": 1.0})
    with plots.styled():
        for fig in (plots.convergence(rows, width=width or plots.WIDTH_PT),
                    plots.work_precision(rows, width=width or plots.WIDTH_PT),
                    plots.compare_convergence({"a": rows, "b": rows}, width=width or plots.WIDTH_PT)):
            page_checks(fig, width or 345.0)  # 345 pt: \textwidth of a default article


def test_failed_level_left_out_of_curves_marked_in_newton():
    rows = synthetic({"L2": 2.0}, failed=(2,))
    h, e = plots.error_curves(rows)["L2"]
    assert list(h) == [0.2, 0.1, 0.025]
    with plots.styled():
        fig = plots.newton({"": rows})
    crosses = [line for line in fig.axes[0].lines if line.get_marker() == "x"]
    assert len(crosses) == 1 and list(crosses[0].get_xdata()) == [rows[2]["dofs"]]


def test_work_precision_leaves_compile_time_out_failed_levels_in():
    rows = synthetic({"L2": 2.0}, failed=(1,))
    for k, row in enumerate(rows):
        row["t_forms"] = 5.0 if k == 0 else 0.0  # level 0 compiled the forms
    with plots.styled():
        fig = plots.work_precision(rows)
    cumulative = fig.axes[0].lines[0].get_xdata()
    times = [row["time_s"] - row["t_forms"] for row in rows]
    assert np.allclose(cumulative, np.cumsum(times)[[0, 2, 3]])  # the failed level's time still counts
    assert "JIT excluded" in fig.axes[0].get_xlabel()  # JIT: the form compilation


def test_compare_is_a_grid_of_one_panel_per_norm_with_one_legend(tmp_path):
    studies = {"a": synthetic({"L2": 2.0, "H1": 1.0, "pos_gc": 1.0}), "b": synthetic({"L2": 1.5})}
    paths = plots.write_comparison(studies, tmp_path)
    assert {p.stem for p in paths} == {"compare_convergence", "compare_work_precision", "compare_newton"}
    with plots.styled():
        fig = plots.compare_convergence(studies)
    assert [len(ax.lines) for ax in fig.axes[:3]] == [2, 1, 1]  # L2: a and b; H1, pos_gc: a only
    rows_of_panels = {round(ax.get_position().y0, 6) for ax in fig.axes}
    assert len(rows_of_panels) == 2  # 345 pt hold two panels a row: three panels take two rows
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend()] + fig.legends
    assert len(legends) == 1 and not fig.axes[3].axison  # in the grid's free place
    assert [t.get_text() for t in legends[0].get_texts()] == ["a", "b"]
    four = {"a": synthetic({"L2": 2.0, "H1": 1.0}), "b": synthetic({"L2": 1.5, "H1": 1.0})}
    with plots.styled():
        fig = plots.compare_convergence(four)
    assert len(fig.axes) == 2 and len(fig.legends) == 1 and not any(ax.get_legend() for ax in fig.axes)


# a log axis' tick labels: 10^k (LogFormatterMathtext), or m×10^k on an axis spanning under two decades
TICK = re.compile(r"\$\\mathdefault\{10\^\{-?\d+\}\}\$|\$(\d(\.\d)?\\times)?10\^\{-?\d+\}\$")
SIX = {"L2": 2.0, "H1": 1.0, "L2_gc": 2.0, "pos_gc": 2.0, "pos_gc_scaled": 3.0, "energy_err": 1.0}


@pytest.mark.fast
@pytest.mark.parametrize("width", [246.0, 345.0, 510.0])
@pytest.mark.parametrize("count", range(1, 8))
def test_panels_fill_their_grid_and_stay_column_sized(width, count):
    sizes = plots.norm_groups(count, width)
    ncols = max(1, int(width // plots.MIN_PANEL_PT))
    assert sum(sizes) == count and max(sizes) - min(sizes) <= 1
    assert len(sizes) <= ncols or len(sizes) % ncols == 0  # no empty place in the grid
    assert plots.figure_height(len(sizes), width, max(sizes)) <= plots.MAX_ASPECT * width


def test_journal_column_figure_at_most_300pt_tall():
    # 246 pt: a two-column journal's \columnwidth; six norms reflow into one panel
    with plots.styled():
        fig = plots.convergence(synthetic(SIX), proven={"L2": 2, "H1": 1}, title="t", width=246.0)
    assert fig.get_figheight() * 72 <= 300 and len(fig.axes) == 1
    page_checks(fig, 246.0)


@pytest.mark.parametrize("width", [246.0, 345.0])
def test_texts_inside_the_axes_clear_of_data_one_tick_format(width):
    with plots.styled():  # drawn as saved: the style's serif font resolves at drawing time
        fig = plots.convergence(synthetic(SIX), proven={"L2": 2, "H1": 1, "pos_gc": 1}, width=width)
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw(renderer)
    for ax in fig.axes:
        box = ax.get_window_extent(renderer)
        points = np.vstack([ax.transData.transform(line.get_xydata()) for line in ax.lines])
        for text in [t.get_window_extent(renderer) for t in ax.texts]:
            assert box.x0 <= text.x0 and text.x1 <= box.x1 and box.y0 <= text.y0 and text.y1 <= box.y1
            assert not any(text.contains(x, y) for x, y in points)  # no marker under a label
        for axis in (ax.xaxis, ax.yaxis):
            labels = [t.get_text() for t in axis.get_ticklabels() if t.get_text()]
            assert labels and all(TICK.fullmatch(t) for t in labels), labels


def test_single_level_study_plots_without_triangles(tmp_path):
    rows = synthetic({"L2": 2.0}, h=H[:1])
    with plots.styled():
        fig = plots.convergence(rows)
    assert triangle_labels(fig.axes[0]) == [] and not fig.axes[0].patches
    assert fig.axes[0].get_legend().get_texts()[0].get_text() == r"$\|u-u_h\|_{L^2}$  (one level)"
    assert sorted(p.name for p in plots.write_all(rows, tmp_path)) == sorted(
        f"{n}.{ext}" for n in ("convergence", "work_precision", "newton") for ext in ("pdf", "png"))


def test_run_without_plots_never_imports_matplotlib(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(merge(BASE, {"output": {"dir": str(tmp_path), "plots": False}})))
    code = ("import sys; from signorini_cli.app import cli; code = cli.main(['run', sys.argv[1], '--quiet']); "
            "assert 'matplotlib' not in sys.modules, 'matplotlib imported'; sys.exit(code)")
    done = subprocess.run([sys.executable, "-c", code, str(cfg)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "t" / "rates.tex").exists() and not list((tmp_path / "t").glob("*.png"))


@pytest.mark.fast
@pytest.mark.parametrize("width_pt", [345.0, 246.0])
def test_pdf_page_is_the_width_in_tex_points_computer_modern(tmp_path, width_pt):
    paths = plots.write_all(synthetic({"L2": 2.0, "H1": 1.0}), tmp_path, width=width_pt)
    pdf = next(p for p in paths if p.name == "convergence.pdf").read_bytes()
    media = re.search(rb"/MediaBox \[\s*0 0 ([\d.]+)", pdf)
    assert float(media[1]) * 72.27 / 72 == pytest.approx(width_pt, abs=0.1)  # bp in the PDF, pt in TeX
    assert b"Cmr10" in pdf and b"STIX" not in pdf and b"DejaVu" not in pdf  # no fallback glyph needed


@pytest.mark.fast
def test_font_key_chooses_stix(tmp_path):
    paths = plots.write_all(synthetic({"L2": 2.0}), tmp_path, font="stix")
    pdf = next(p for p in paths if p.name == "convergence.pdf").read_bytes()
    assert b"STIXGeneral" in pdf and b"Cmr10" not in pdf


@pytest.mark.fast
def test_twelve_curves_twelve_styles():
    styles = [tuple(map(str, plots.curve_style(i).values())) for i in range(12)]
    assert len(set(styles)) == 12


@pytest.mark.fast
def test_sub_study_legends_are_their_values():
    assert plots.legend_of("alpha1.5-p2") == r"$\alpha = 1.5$, $p = 2$"
    assert plots.legend_of("signorini") == "Signorini VI"
