"""Rate tables for papers (Markdown, LaTeX), and a study read back from study.h5 or rates.csv."""
import os
import shutil
import subprocess
import textwrap
from pathlib import Path

import pytest

from signorini_cli import config, studies
from signorini_cli.record import results
from signorini_cli.report import tables


def row(level, n, h, converged=True, L2=None, rate_L2=None, H1=None, rate_H1=None):
    return {"level": level, "N": n, "h": h, "dofs": (n + 1) ** 2, "epsilon": h, "converged": converged,
            "newton_its": 5, "L2": L2, "rate_L2": rate_L2, "H1": H1, "rate_H1": rate_H1, "time_s": 0.5,
            "reason": "CONVERGED_FNORM_ABS" if converged else "DIVERGED_MAX_IT"}


# the LaTeX checks skip without pdflatex, except under `make test` (which installs it): there they fail
needs_pdflatex = pytest.mark.skipif(not shutil.which("pdflatex") and not os.environ.get("SIGNORINI_REQUIRE_LATEX"),
                                    reason="pdflatex not installed (make setup installs it)")
KNOWN = [row(0, 8, 0.25, L2=0.01, H1=0.5),
         row(1, 16, 0.125, L2=0.0025, rate_L2=2.0, H1=0.25, rate_H1=1.0),
         row(2, 32, 0.0625, converged=False)]


def test_markdown_table_known():
    # h = 2/N on every level: N gives h, so the paper's columns leave it out
    assert tables.markdown_table(KNOWN, digits=2) == (
        "| N | ε | its | L² error | L² rate | H¹ error | H¹ rate |\n"
        "|---:|---:|---:|---:|---:|---:|---:|\n"
        "| 8 | 2.50e-01 | 5 | 1.00e-02 | – | 5.00e-01 | – |\n"
        "| 16 | 1.25e-01 | 5 | 2.50e-03 | 2.00 | 2.50e-01 | 1.00 |\n"
        "| 32 | 6.25e-02 | 5 (failed) | – | – | – | – |\n"
        "\n"
        "Level 2 (N = 32) did not converge: DIVERGED_MAX_IT.\n")


def test_latex_table_grouped_with_definitions_in_caption():
    lines = tables.latex_table(KNOWN[:2], digits=3, caption="Study t", key="tab:t").splitlines()
    assert lines[0].endswith(r"needs \usepackage{booktabs}")
    assert lines[1] == r"% layout: fits \textwidth at the normal size"
    assert lines[2:4] == [r"\begin{table}", r"\centering"]
    caption = lines[4]
    # h = 2/N and ε = h on every level: the caption says so, the table shows neither column
    # and its = 5 on every level: a column the caption fixes
    assert caption.startswith(r"\caption{Study t. $N$: cells per side, $h = 2/N$ the largest cell diameter; "
                              r"its = $5$; $\varepsilon = h$; $|\cdot|_{H^1}$: the $H^1(\Omega)$ seminorm")
    assert caption.endswith("successive levels.}")
    assert lines[5:] == [
        r"\label{tab:t}", r"\setlength{\tabcolsep}{3pt}",
        r"\begin{tabular}{rrrrr}", r"\toprule",
        r" & \multicolumn{2}{c}{$\|u-u_h\|_{L^2}$} & \multicolumn{2}{c}{$|u-u_h|_{H^1}$} \\",
        r"\cmidrule(lr){2-3} \cmidrule(lr){4-5}",
        r"$N$ & error & rate & error & rate \\", r"\midrule",
        r"8 & $1.000\times10^{-2}$ & -- & $5.000\times10^{-1}$ & -- \\",
        r"16 & $2.500\times10^{-3}$ & 2.00 & $2.500\times10^{-1}$ & 1.00 \\",
        r"\bottomrule", r"\end{tabular}", r"\end{table}"]


def test_latex_table_unknown_norm_escaped():
    rows = [dict(KNOWN[0], L2_gamma_c=0.1, rate_L2_gamma_c=None)]
    assert r"\multicolumn{2}{c}{L2 gamma c}" in tables.latex_table(rows, columns="all")  # words, no code


def test_tables_without_norms_data_only_scene():
    rows = [{k: v for k, v in KNOWN[0].items() if k not in ("L2", "rate_L2", "H1", "rate_H1")}]
    assert tables.markdown_table(rows).splitlines()[0] == "| N | ε | its |"


def demo_like(levels=7):
    """A 2-D α = 2, ε = h study's table (values as `signorini run configs/demo.yaml`, N = 8..512 gives):
    six norms, their rates, every timing column, h = √2/N."""
    rows = []
    for k in range(levels):
        n = 8 * 2**k
        row = {"level": k, "N": n, "h": 2**0.5 / n, "dofs": (n + 1) ** 2, "epsilon": 2**0.5 / n,
               "converged": True, "newton_its": 2, "time_s": 0.01 * 4**k, "reason": "CONVERGED_FNORM_ABS"}
        for norm, (e0, p) in {"L2": (2.3e-2, 2), "H1": (0.574, 1), "L2_gc": (5.3e-2, 2), "pos_gc": (2.8e-2, 2),
                              "pos_gc_scaled": (4.7e-3, 3), "energy_err": (0.574, 1)}.items():
            row[norm], row[f"rate_{norm}"] = e0 / 2 ** (p * k), float(p) if k else None
        row.update({f"t_{what}": 1e-3 for what in ("mesh", "forms", "newton", "errors", "output")})
        rows.append(row)
    return rows


DEMO = config.load(Path(__file__).resolve().parents[2] / "configs" / "demo.yaml")


def test_paper_columns_are_the_norms_the_paper_bounds():
    # configs/demo.yaml: L2 (Lemma 4.2), H1 (Cor. 3.2 i), [u]_+ on Γ_C (Cor. 3.2 ii), energy (Lemma 3.1);
    # no rate for L2 on Γ_C; the scaled [u]_+ is a power of the unscaled one
    lead, shown = tables.choose(demo_like(), "paper", tables.proven_rates(DEMO))
    assert lead == ["N", "epsilon", "newton_its"] and shown == ["L2", "H1", "pos_gc", "energy_err"]


def test_terminal_table_fits_120_columns_all_one_option_away():
    rows = demo_like()
    default = tables.format_table(rows, DEMO).splitlines()
    assert max(map(len, default)) <= 120 and len(default) == 2 + len(rows)
    everything = tables.format_table(rows, DEMO, columns="all").splitlines()
    assert max(map(len, everything)) <= 120  # wrapped into blocks, each led by the level again
    blocks = "\n".join(everything).split("\n\n")
    assert all("level" in [line.split()[0] for line in block.splitlines()[:2]] for block in blocks)  # under titles
    assert all(column in "\n".join(everything) for column in ("dofs", "t_forms", "converged", "energy_err"))


def test_columns_list_and_unknown_column():
    lead, shown = tables.choose(KNOWN, ["N", "h", "L2"])
    assert (lead, shown) == (["N", "h"], ["L2"])
    with pytest.raises(config.ConfigError, match="output.columns: 'L3' is not a column of this study"):
        tables.choose(KNOWN, ["N", "L3"])


def test_h_kept_when_n_does_not_give_it():
    rows = [dict(row, h=row["h"] * (1 + 0.1 * k)) for k, row in enumerate(KNOWN)]  # gmsh-like sizes
    assert tables.choose(rows)[0] == ["N", "h", "epsilon", "newton_its"]


@needs_pdflatex
def test_default_latex_table_fits_a_default_article(tmp_path):
    (tmp_path / "rates.tex").write_text(tables.latex_table(demo_like(), 3, "Study demo",
                                                           proven=tables.proven_rates(DEMO)))
    (tmp_path / "doc.tex").write_text("\\documentclass{article}\n\\usepackage{booktabs}\n"
                                      "\\begin{document}\n\\input{rates.tex}\n\\end{document}\n")
    done = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "doc.tex"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:]
    assert "Overfull" not in (tmp_path / "doc.log").read_text()


def test_summary_table_one_line_per_study():
    lines = tables.summary_table({"a": KNOWN, "b": KNOWN[:1]}).splitlines()
    assert lines[0].split() == ["L²", "H¹"] and lines[1].split()[:4] == ["study", "levels", "finest", "h"]
    # a: finest converged level N = 16 (h = 0.125), 1.5 s in all; L2 from 1e-2 to 2.5e-3 as h halves: slope 2
    assert lines[2].split() == ["a", "3", "1.250e-01", "1.50", "2.500e-03", "2.00", "2.500e-01", "1.00"]
    assert lines[3].split() == ["b", "1", "2.500e-01", "0.50", "1.000e-02", "-", "5.000e-01", "-"]


@pytest.mark.parametrize("name", ["study.h5", "rates.csv", ""])
def test_load_partial_study(partial_study, name):
    loaded = results.load(partial_study.output_dir / name)
    assert loaded.name == "t" and [r["N"] for r in loaded.rows] == [4, 8]
    assert list(loaded.rows[0])[:len(studies.level.LEADING_COLUMNS)] == list(studies.level.LEADING_COLUMNS)
    assert loaded.rows[0]["rate_L2"] is None and loaded.rows[1]["rate_L2"] > 1
    assert loaded.rows[1]["converged"] is True and isinstance(loaded.rows[1]["dofs"], int)


def test_load_h5_and_csv_agree(partial_study):
    from_h5, from_csv = (results.load(partial_study.output_dir / n) for n in ("study.h5", "rates.csv"))
    assert from_h5.rows == from_csv.rows  # CSV floats are repr(): exact
    assert config.loads(from_h5.config_text).mesh.refinements == (4, 8, 16)  # the resolved config


def test_load_missing_path_names_problem(tmp_path):
    with pytest.raises(FileNotFoundError, match="not a study folder"):
        results.load(tmp_path)


def cut_csv(folder):
    text = (folder / "rates.csv").read_text()
    (folder / "rates.csv").write_text(text[:len(text) - 40])  # the last row loses its last fields


def nan_in_n(folder):
    lines = (folder / "rates.csv").read_text().splitlines()
    lines[2] = lines[2].replace(",8,", ",nan,", 1)  # level 1 has N = 8
    (folder / "rates.csv").write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("damage, message", [
    pytest.param(cut_csv, "rates.csv: damaged, row 2 does not have the header's", id="cut"),
    pytest.param(nan_in_n, "rates.csv: damaged, N = nan at level 1", id="nan"),
])
def test_damaged_csv_names_the_file(partial_study, damage, message):
    folder = partial_study.output_dir
    damage(folder)
    with pytest.raises(results.DamagedResults, match=message):
        results.load(folder / "rates.csv")


def drop_table(folder):
    import h5py
    with h5py.File(folder / "study.h5", "a") as h5:
        del h5["table"]


def truncate_h5(folder):
    data = (folder / "study.h5").read_bytes()
    (folder / "study.h5").write_bytes(data[:len(data) // 3])


@pytest.mark.parametrize("damage", [drop_table, truncate_h5])
def test_damaged_h5_falls_back_to_rates_csv(partial_study, damage, caplog):
    folder = partial_study.output_dir
    intact = results.load(folder / "rates.csv").rows
    damage(folder)
    assert results.load(folder).rows == intact
    assert "study.h5: damaged" in caplog.text and "reading" in caplog.text
    cut_csv(folder)
    with pytest.raises(results.DamagedResults, match="study.h5: damaged.*; .*rates.csv: damaged"):
        results.load(folder)


@pytest.mark.fast
def test_signorini_problem_table_shows_contact_set_not_eps():
    # ε = 0 on every level (the variational inequality): no ε column; the contact set's measure instead
    rows = [dict(row, epsilon=0.0, contact_measure=0.5) for row in demo_like(3)]
    lead, _ = tables.choose(rows, "paper")
    assert lead == ["N", "newton_its", "contact_measure"]
    assert max(map(len, tables.format_table(rows).splitlines())) <= 120


@pytest.mark.fast
def test_reference_norms_scaled_left_out_beside_unscaled():
    measured = ["L2_ref", "H1_ref", "pos_gc_ref", "pos_gc_scaled_ref"]
    proven = {n: 1.0 for n in measured}
    assert tables.paper_norms(measured, proven) == ["L2_ref", "H1_ref", "pos_gc_ref"]


def test_columns_choose_the_plotted_norms(tmp_path, monkeypatch):
    from signorini_cli.report import plots
    drawn, convergence = [], plots.convergence

    def recorded(rows, *args):
        fig = convergence(rows, *args)
        drawn.append([line.get_label().split()[0] for ax in fig.axes for line in ax.lines])
        return fig
    monkeypatch.setattr(plots, "convergence", recorded)
    study = results.Study("demo", tmp_path, demo_like(3))
    tables.write(study, DEMO, columns=["N", "H1"], suffix="-N-H1")
    assert (tmp_path / "rates-N-H1.tex").exists() and not (tmp_path / "rates.tex").exists()
    assert drawn == [[r"$|u-u_h|_{H^1}$"]]


@pytest.mark.fast
def test_wide_rows_wrapped_at_120_columns_nothing_lost():
    # an ε → 0 reference table: about 20 columns of .3e numbers, some 200 characters on one line
    rows = [{"N": n, **{f"column_{k}": 1.0 / (n + k) for k in range(20)}} for n in (8, 16, 32)]
    lines = tables.format_rows(rows).splitlines()
    assert max(map(len, lines)) <= 120
    text = "\n".join(lines)
    assert all(f"column_{k}" in text for k in range(20)) and text.count("\n\n") >= 1
    assert all(block.splitlines()[0].split()[0] == "N" for block in text.split("\n\n"))


def test_wrote_line_wraps_between_names():
    """A map's closing line (15 figures and tables) wraps at 120 columns between whole file names."""
    names = ["map.csv", "map.tex", "map.md"] + [f"{kind}_{norm}_alpha_epsilon-theta.{ext}" for kind in ("heat", "rate")
                                                  for norm in ("L2", "H1") for ext in ("png", "pdf")]
    lines = tables.wrote(names).splitlines()
    assert len(lines) > 1 and all(len(line) <= 120 for line in lines)
    assert lines[0].startswith("wrote map.csv, ") and all(line.startswith("  ") for line in lines[1:])
    assert "".join(lines).replace("  ", " ").removeprefix("wrote ").split(", ") == names
    assert tables.wrote(["rates.md"], "/tmp/x") == "wrote into /tmp/x: rates.md"
    # a total-error study: its sub-studies' files counted per folder, not listed one by one
    subs = [f"alpha{a}-p{q}/{f}" for a in (1, 2, 3) for q in (1, 2, 3) for f in ("rates.md", "rates.tex", "a.pdf")]
    assert tables.wrote(["total.md"] + subs) == textwrap.fill(
        "wrote total.md, " + ", ".join(f"alpha{a}-p{q}/ (3 files)" for a in (1, 2, 3) for q in (1, 2, 3)), 120,
        subsequent_indent="  ", break_long_words=False, break_on_hyphens=False)


def test_all_columns_put_the_errors_before_the_timings():
    rows = [dict(row, t_mesh=0.1, peak_memory_mb=12.0) for row in demo_like(3)]
    text = tables.format_table(rows, columns="all")
    header = next(line for line in text.splitlines() if "newton_its" in line)
    assert header.index("newton_its") < header.index("error")  # the level, its errors, then how long it took
    assert all(text.index("H1") < text.index(late) for late in ("time_s", "t_mesh", "peak_memory_mb"))
