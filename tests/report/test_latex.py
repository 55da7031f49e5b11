"""LaTeX of the rate tables: escaped text, numbers, the config's expressions typeset, and tables that
compile in a plain article without an overfull box whatever the columns."""
import re
import subprocess
from pathlib import Path

import pytest
import yaml

from signorini_cli import config
from signorini_cli.config import expressions
from signorini_cli.report import latex, tables
from test_report import DEMO, demo_like, needs_pdflatex

ROOT = Path(__file__).resolve().parents[2]

HOSTILE = [r"\input{/etc/passwd}", r"\write18{touch x}", "$x$ & 50% #1 ~ ^^5c", "{}}{", "é\x00\n"]
SAFE_COMMAND = re.compile(r"\\(textbackslash|textasciitilde|textasciicircum|textless|textgreater|textbar)\{\}|"
                          r"\\[&%$#_{}]|\$\\[a-zA-Z]+\$")


@pytest.mark.fast
@pytest.mark.parametrize("text", HOSTILE)
def test_escape_leaves_no_command(text):
    escaped = latex.escape(text)
    assert "\\" not in SAFE_COMMAND.sub("", escaped)  # every backslash is one of the escapes
    assert not re.search(r"(?<!\\)[{}$&%#~^]", SAFE_COMMAND.sub("", escaped))


@pytest.mark.fast
@pytest.mark.parametrize("source, tex", [
    ("sin(2*pi*x)*(1-y)**2", r"\sin(2 \pi x) (1 - y)^{2}"),
    ("x/(1+y)", r"\frac{x}{1 + y}"),
    ("-x**2", "-x^{2}"),
    ("2*3*x", r"2 \cdot 3 x"),
    ("x-(y-z)", "x - (y - z)"),
    ("x-y+z", "x - y + z"),
    ("sqrt(abs(x))*exp(-eps)", r"\sqrt{|x|} \exp(-\varepsilon)"),
    ("1e-6*x + 0.5", r"10^{-6} x + 0.5"),
    ("sin(x)**2", r"(\sin(x))^{2}"),
    ("(x*y)**2", "(x y)^{2}"),
    ("x**(1/2)", r"x^{\frac{1}{2}}"),
])
def test_expression_typeset(source, tex):
    assert latex.expression(expressions.parse(source, {"x", "y", "z", "eps"}).tree) == tex


@pytest.mark.fast
def test_numbers_one_format():
    assert latex.number(0.023034, 3) == r"$2.303\times10^{-2}$"
    assert latex.number(1.0, 2) == r"$1.00\times10^{0}$"  # 10^0 too: one format down a column
    assert latex.number(float("nan"), 3) == "nan" and latex.rate(-0.351) == "$-0.35$"


@pytest.mark.fast
def test_text_cell_escaped_in_latex_and_markdown():
    rows = [dict(row, reason=r"\input{/etc/passwd}|x") for row in demo_like(2)]
    tex = tables.latex_table(rows, columns=["N", "reason", "L2"])
    assert r"\input" not in tex and r"\textbackslash{}input\{/etc/passwd\}\textbar{}x" in tex
    assert r"\input{/etc/passwd}\|x" in tables.markdown_table(rows, columns=["N", "reason", "L2"])


@pytest.mark.fast
def test_caption_from_the_study_fields():
    caption = tables.caption_of("demo_1", DEMO)
    assert caption == (r"Errors and observed rates: $d = 2$, $\alpha = 2$, $\varepsilon = h$, exact solution "
                       r"$u = \sin(2 \pi x) (1 - y)^{2}$, contact boundary $\Gamma_C$: bottom")  # no slug by default
    assert tables.caption_of("demo_1", DEMO, slug=True).startswith(r"Study demo\_1: $d = 2$")
    data = config.load(Path(__file__).resolve().parents[2] / "configs" / "paper" / "data-push-constant-eps.yaml")
    assert "data $f = " in tables.caption_of("d", data) and r"$\varepsilon = " in tables.caption_of("d", data)


@pytest.mark.fast
def test_redundant_columns_stated_in_the_caption():
    # gmsh-like: N cells of a uniformly refined 2-D mesh, h = 3.5 N^{-1/2}, ε = h
    rows = [dict(row, N=190 * 4**k, h=3.5 / (190 * 4**k) ** 0.5, epsilon=3.5 / (190 * 4**k) ** 0.5)
            for k, row in enumerate(demo_like(3))]
    tex = tables.latex_table(rows, columns=["N", "h", "epsilon", "L2"])
    assert r"$N$: the number of cells, $h = 3.5\,N^{-1/2}$" in tex and r"$\varepsilon = h$" in tex
    assert r"$N$ & error & rate \\" in tex  # neither h nor ε as a column


def widest(rows):
    """Columns that cannot fit one line of an article: all of them."""
    return tables.latex_table(rows, columns="all", key="tab:all")


@pytest.mark.fast
def test_layout_chosen_and_said():
    assert tables.latex_table(demo_like()[:2], columns=["N", "L2"]).splitlines()[1] == (
        r"% layout: fits \textwidth at the normal size")
    tex = widest(demo_like())
    assert "stacked parts" in tex.splitlines()[1] and tex.count(r"\begin{tabular}") >= 2
    assert tex.count(r"\label{") == 1 and tex.count(r"\caption{") == 1  # one float, one caption


def data_only_like(levels=5):
    """A gmsh L-shape data-only study's rows (configs/gmsh/l-shape-data-only.yaml: N = 190·4^k cells,
    h = 3.489 N^(-1/2), ε = h), its errors against the reference and the contact set's measure."""
    rows = []
    for k, row in enumerate(demo_like(levels)):
        n = 190 * 4**k
        row = dict(row, N=n, h=3.489 / n**0.5, epsilon=3.489 / n**0.5, contact_measure=1.0)
        for norm in ("L2", "H1"):
            row[f"{norm}_ref"], row[f"rate_{norm}_ref"] = row.pop(norm), row.pop(f"rate_{norm}")
        for norm in ("L2_gc", "pos_gc"):
            row[f"{norm}_ref"], row[f"rate_{norm}_ref"] = row[norm], row[f"rate_{norm}"]
        rows.append(row)
    return rows


DATA_ONLY = config.load(Path(__file__).resolve().parents[2] / "configs" / "gmsh" / "l-shape-data-only.yaml")
CASES = {
    "data-only-columns": lambda: tables.latex_table(
        data_only_like(), 3, tables.caption_of("gmsh-l-shape-data-only", DATA_ONLY),
        columns=["N", "h", "epsilon", "L2_ref", "H1_ref", "L2_gc_ref", "pos_gc_ref", "contact_measure"]),
    "signorini-problem": lambda: tables.latex_table([dict(r, epsilon=0.0, contact_measure=0.5) for r in demo_like()]),
    "demo-paper": lambda: tables.latex_table(demo_like(), 3, tables.caption_of("demo", DEMO),
                                             proven=tables.proven_rates(DEMO), key="tab:demo"),
    "demo-all": lambda: widest(demo_like()),
    "digits-6": lambda: tables.latex_table(demo_like(), 6, columns=["N", "h", "epsilon", "dofs", "L2", "H1",
                                                                    "L2_gc", "pos_gc", "energy_err"]),
    "long-column-name": lambda: tables.latex_table([dict(r, **{"x_" * 60: 1.5}) for r in demo_like(3)],
                                                   columns=["N", "x_" * 60, "L2"]),
    "hostile-text": lambda: tables.latex_table([dict(r, reason=HOSTILE[0] * 3) for r in demo_like(3)],
                                               columns=["N", "reason", "L2", "H1"]),
}


@needs_pdflatex
@pytest.mark.parametrize("case", CASES)
def test_tables_compile_in_a_plain_article_without_overfull_box(tmp_path, case):
    assert compile_log(tmp_path, CASES[case]()).count("Overfull") == 0


def compile_log(folder, tex, packages="booktabs", name="rates.tex"):
    """pdflatex's log of `tex` \\input into \\documentclass{article} with `packages` (its header names booktabs)."""
    (folder / name).write_text(tex)
    (folder / "doc.tex").write_text(f"\\documentclass{{article}}\n\\usepackage{{{packages}}}\n"
                                    f"\\begin{{document}}\nText.\n\n\\input{{{name}}}\n\\end{{document}}\n")
    done = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "-no-shell-escape",
                           "doc.tex"], cwd=folder, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:]
    return (folder / "doc.log").read_text()


@pytest.mark.fast
def test_caption_of_an_elastic_study_typesets_the_vector_solution():
    cfg = config.load(ROOT / "configs/elasticity/square-alpha2.yaml")
    caption = tables.caption_of(cfg.study, cfg)
    assert r"$u = \left(" in caption and r"\right)$" in caption


@pytest.mark.fast
@pytest.mark.parametrize("name", expressions.FUNCTIONS)
def test_every_function_of_the_expression_language_typesets(name):
    # a caption typesets whatever a config may write: a function missing here once crashed a study's rates.tex
    arguments = ", ".join(["x", "y"][:expressions.ARITY.get(name, 1)])
    tex = latex.expression(expressions.parse(f"{name}({arguments})", {"x", "y"}).tree)
    assert tex.endswith(f"({arguments})") or tex in (r"\sqrt{x}", "|x|")


# every study type on coarse levels (about a minute in all): (config, overrides)
STUDY_TYPES = {
    "refinement": ("configs/paper/square-alpha2-theta-small.yaml", ["mesh.refinements=[4,8,16]"]),
    "data-only": ("configs/paper/data-push-theta-h.yaml", ["mesh.refinements=[4,8,16]"]),
    "p2": ("configs/elements/p2-square-alpha2.yaml", ["mesh.refinements=[4,8,16]"]),
    "elasticity": ("configs/elasticity/square-alpha2.yaml", ["mesh.refinements=[4,8,16]"]),
    "hertz": ("configs/elasticity/hertz.yaml", ["mesh.sizes=[0.2,0.1,0.05]"]),
    "signorini": ("configs/limit/signorini.yaml", ["mesh.refinements=[4,8,16]"]),
    "epsilon_sweep": ("configs/limit/sweep.yaml", ["mesh.refinements=[4,8]", "limit.epsilon.count=3",
                                                   "limit.epsilon.stop=1e-4"]),
    "total_error": ("configs/limit/total.yaml", ["mesh.refinements=[4,8,16]", "limit.alpha=[1,2]",
                                                 "limit.exponent=[1,2]"]),
}


MAP = {"study": "m", "study_type": "map", "dimension": 2, "alpha": 2.0, "epsilon": {"law": "theta_h", "theta": 1.0},
       "mesh": {"kind": "unit_square", "refinements": [4, 8, 16]}, "contact": "bottom",
       "problem": {"exact": "sin(2*pi*x)*(1-y)**2"}, "map": {"grid": {"epsilon.theta": [0.1, 10], "alpha": [1, 2]}}}


def run_kind(kind, out):
    """Run a study of `kind` (a key of STUDY_TYPES, map or compare: of two refinement studies) into `out`."""
    from signorini_cli.app import cli
    if kind == "map":
        (out.parent / "map.yaml").write_text(yaml.safe_dump(MAP))
        return cli.main(["run", str(out.parent / "map.yaml"), "--output", str(out), "--quiet"])
    if kind == "compare":
        for k in ("refinement", "p2"):
            run_kind(k, out / k)
        return cli.main(["compare", *map(str, sorted(out.glob("*/*/"))), "--label", "α=2", "--label", "p = 2"])
    path, overrides = STUDY_TYPES[kind]
    sets = [arg for o in overrides for arg in ("--set", o)]
    return cli.main(["run", str(ROOT / path), "--output", str(out), "--quiet", *sets])


@needs_pdflatex
@pytest.mark.parametrize("kind", list(STUDY_TYPES) + ["map", "compare"])
def test_every_tex_of_a_study_type_is_one_float_that_compiles_cleanly(tmp_path, kind):
    assert run_kind(kind, tmp_path / "out") in (0, 1)
    written = sorted((tmp_path / "out").rglob("*.tex"))
    assert written and (kind != "compare" or any(t.name == "compare.tex" for t in written))
    for tex in written:
        text = tex.read_text()
        assert text.count(r"\begin{table}") == 1 and text.count(r"\label{") == 1, tex
        log = compile_log(tex.parent, text, packages="booktabs,amsmath,graphicx", name=tex.name)
        assert not re.search(r"^(Overfull|Underfull|!)|Float too large", log, re.M), (tex, log[-2000:])
