"""Rate tables for papers (Markdown, LaTeX), and a study read back from study.h5 or rates.csv."""
import pytest

from signorini_cli import config, report, results, study


def row(level, n, h, converged=True, L2=None, rate_L2=None, H1=None, rate_H1=None):
    return {"level": level, "N": n, "h": h, "dofs": (n + 1) ** 2, "epsilon": h, "converged": converged,
            "newton_its": 5, "L2": L2, "rate_L2": rate_L2, "H1": H1, "rate_H1": rate_H1, "time_s": 0.5,
            "reason": "CONVERGED_FNORM_ABS" if converged else "DIVERGED_MAX_IT"}


KNOWN = [row(0, 8, 0.25, L2=0.01, H1=0.5),
         row(1, 16, 0.125, L2=0.0025, rate_L2=2.0, H1=0.25, rate_H1=1.0),
         row(2, 32, 0.0625, converged=False)]


def test_markdown_table_known():
    assert report.markdown_table(KNOWN, digits=2) == (
        "| N | h | DoFs | ε | Newton | ‖u − u_h‖_L²(Ω) | rate | \\|u − u_h\\|_H¹(Ω) | rate |\n"
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
        "| 8 | 2.50e-01 | 81 | 2.50e-01 | 5 | 1.00e-02 | – | 5.00e-01 | – |\n"
        "| 16 | 1.25e-01 | 289 | 1.25e-01 | 5 | 2.50e-03 | 2.00 | 2.50e-01 | 1.00 |\n"
        "| 32 | 6.25e-02 | 1089 | 6.25e-02 | 5 (failed) | – | – | – | – |\n"
        "\n"
        "Level 2 (N = 32) did not converge: DIVERGED_MAX_IT.\n")


def test_latex_table_known():
    assert report.latex_table(KNOWN[:2], digits=3, caption="study t") == (
        "% study t\n"
        "\\begin{tabular}{rrrrrrrrr}\n"
        "\\toprule\n"
        "$N$ & $h$ & DoFs & $\\varepsilon$ & Newton & $\\|u-u_h\\|_{L^2(\\Omega)}$ & rate"
        " & $|u-u_h|_{H^1(\\Omega)}$ & rate \\\\\n"
        "\\midrule\n"
        "8 & $2.500 \\cdot 10^{-1}$ & 81 & $2.500 \\cdot 10^{-1}$ & 5 & $1.000 \\cdot 10^{-2}$ & --"
        " & $5.000 \\cdot 10^{-1}$ & -- \\\\\n"
        "16 & $1.250 \\cdot 10^{-1}$ & 289 & $1.250 \\cdot 10^{-1}$ & 5 & $2.500 \\cdot 10^{-3}$ & 2.00"
        " & $2.500 \\cdot 10^{-1}$ & 1.00 \\\\\n"
        "\\bottomrule\n"
        "\\end{tabular}\n")


def test_latex_table_unknown_norm_escaped():
    rows = [dict(KNOWN[0], L2_gamma_c=0.1, rate_L2_gamma_c=None)]
    assert r"\texttt{L2\_gamma\_c} & rate" in report.latex_table(rows)


def test_tables_without_norms_data_only_scene():
    rows = [{k: v for k, v in KNOWN[0].items() if k not in ("L2", "rate_L2", "H1", "rate_H1")}]
    assert report.markdown_table(rows).splitlines()[0] == "| N | h | DoFs | ε | Newton |"


def test_fitted_slope_known_power_law():
    h = [0.4, 0.2, 0.1, 0.05]
    assert report.fitted_slope(h, [3 * x**1.5 for x in h]) == pytest.approx(1.5, rel=1e-12)
    assert report.fitted_slope(h[:1], [1.0]) is None


def test_summary_table_one_line_per_study():
    text = report.summary_table({"a": KNOWN, "b": KNOWN[:1]})
    lines = text.splitlines()
    assert lines[0].split()[:3] == ["study", "levels", "finest"] and len(lines) == 3
    assert lines[1].split()[:3] == ["a", "3", "1.250e-01"] and " 2.00 " in lines[1]




@pytest.mark.parametrize("name", ["study.h5", "rates.csv", ""])
def test_load_partial_study(partial_study, name):
    loaded = report.load(partial_study.output_dir / name)
    assert loaded.name == "t" and [r["N"] for r in loaded.rows] == [4, 8]
    assert list(loaded.rows[0])[:len(results.SPEC_COLUMNS)] == list(results.SPEC_COLUMNS)
    assert loaded.rows[0]["rate_L2"] is None and loaded.rows[1]["rate_L2"] > 1
    assert loaded.rows[1]["converged"] is True and isinstance(loaded.rows[1]["dofs"], int)


def test_load_h5_and_csv_agree(partial_study):
    from_h5, from_csv = (report.load(partial_study.output_dir / n) for n in ("study.h5", "rates.csv"))
    assert from_h5.rows == from_csv.rows  # CSV floats are repr(): exact
    assert config.loads(from_h5.config_text).mesh.refinements == (4, 8, 16)  # the resolved config


def test_load_missing_path_names_problem(tmp_path):
    with pytest.raises(FileNotFoundError, match="not a study folder"):
        report.load(tmp_path)
