"""The measures a study can take and the names of a study table's columns, in one place: what each
measure fills, needs and is bounded by (config, verification), the short name a header or an axis shows
and the definition a caption gives (report's tables, plots' axes and legends, progress lines)."""
from dataclasses import dataclass


@dataclass(frozen=True)
class Name:
    """text: plain Unicode (terminal, Markdown, figures); tex and definition: LaTeX in text mode (a
    header, a caption), no package beyond a default article."""
    text: str
    tex: str
    definition: str


# the error norms (the paper's bounds: Lemma 3.1, Corollary 3.2, Lemma 4.2); H1 is the seminorm. tex: the norm
# itself as a header; definition: what the header leaves to the caption (empty: nothing)
NORMS = {
    "L2": Name("L²", r"$\|u-u_h\|_{L^2}$", ""),
    "H1": Name("H¹", r"$|u-u_h|_{H^1}$", r"$|\cdot|_{H^1}$: the $H^1(\Omega)$ seminorm"),
    "L2_gc": Name("L²(Γ_C)", r"$\|u-u_h\|_{L^2(\Gamma_C)}$", ""),
    "pos_gc": Name("[·]+ on Γ_C", r"$\|[u]_+-[u_h]_+\|_{L^{\alpha+1}(\Gamma_C)}$", ""),
    "pos_gc_scaled": Name("[·]+ scaled", r"$\|[u]_+-[u_h]_+\|_{L^{\alpha+1}(\Gamma_C)}^{(\alpha+1)/2}$", ""),
    "energy_err": Name("energy", r"$e_\varepsilon$",
                       r"$e_\varepsilon = (|u-u_h|_{H^1}^2"
                       r"+\varepsilon^{-1}\|[u]_+-[u_h]_+\|_{L^{\alpha+1}(\Gamma_C)}^{\alpha+1})^{1/2}$ (Lemma 3.1)"),
}
# the columns before the errors
COLUMNS = {
    "level": Name("level", "level", "the refinement level"),
    "N": Name("N", "$N$", "cells per side (gmsh and file meshes: the number of cells)"),
    "h": Name("h", "$h$", "the largest cell diameter"),
    "dofs": Name("DoFs", "DoFs", "the number of unknowns"),
    "epsilon": Name("ε", r"$\varepsilon$", "the penalty parameter"),
    "newton_its": Name("its", "its", "Newton iterations"),
    "time_s": Name("time", "time", "wall time of the level in seconds"),
    # a Hertz contact (hertz: {radius}): measured, Hertz's closed form, relative error
    "half_width": Name("a_h", "$a_h$", "the contact half-width"),
    "half_width_hertz": Name("a(F_h)", "$a(F_h)$", "Hertz's half-width under the force $F_h$"),
    "half_width_err": Name("a err", r"$|a_h-a|/a$", "the half-width's relative error"),
    "peak_pressure": Name("p_h", "$p_h$", "the central contact pressure, Hertz's $p_0$ as measured"),
    "peak_pressure_hertz": Name("p0(F_h)", "$p_0(F_h)$", "Hertz's peak pressure under the force $F_h$"),
    "peak_pressure_err": Name("p err", r"$|p_h-p_0|/p_0$", "the peak pressure's relative error"),
    "force_hertz": Name("F(a_h)", "$F(a_h)$", "Hertz's force for the half-width $a_h$"),
    "force_err": Name("F err", r"$|F_h-F|/F$", "the force's relative error"),
    "alpha": Name("α", r"$\alpha$", ""),
    "p": Name("p", "$p$", ""),
}
HERTZ = ("contact_force",) + tuple(c for c in COLUMNS if c.startswith(("half_width", "peak_pressure", "force_")))


def name(column):
    """The Name of any column; a reference norm X_ref reads "X ref", an unknown column its own name."""
    if column in NORMS:
        return NORMS[column]
    if column in COLUMNS:
        return COLUMNS[column]
    if column.endswith("_ref") and column[:-4] in NORMS:
        base = NORMS[column[:-4]]
        ref = r"u_{\mathrm{ref}}"
        return Name(base.text + " ref", *(text.replace("u-u_h", ref + "-u_h").replace("[u]_+", f"[{ref}]_+")
                                          for text in (base.tex, base.definition)))
    plain = column.replace("_", " ")
    return Name(plain, r"\texttt{" + column.replace("_", r"\_") + "}", plain.replace("_", r"\_"))


@dataclass(frozen=True)
class Measure:
    """A `verification.measures` entry beyond L2/H1: the table columns it fills, an error (with a rate) or
    a quantity (a value), whether it needs a Γ_C face, the scenes (exact, data) that take it by default,
    and the paper's result that bounds it (empty: none)."""
    key: str
    columns: tuple
    kind: str
    contact: bool
    default: tuple
    paper: str = ""


BOTH = ("exact", "data")
MEASURES = (
    Measure("L2_gc", ("L2_gc",), "error", True, BOTH),
    Measure("pos_gc", ("pos_gc", "pos_gc_scaled"), "error", True, BOTH, "Cor. 3.2 ii"),
    Measure("energy_err", ("energy_err",), "error", True, BOTH, "Lemma 3.1"),
    Measure("penetration", ("penetration",), "quantity", True, BOTH),
    Measure("contact_measure", ("contact_measure",), "quantity", True, BOTH),
    Measure("contact_force", ("contact_force",), "quantity", True, ("data",)),
    Measure("energy", ("energy",), "quantity", False, ("data",)),
    Measure("hertz", HERTZ[1:], "quantity", True, ()),  # with a hertz block: against Hertz's closed forms
    Measure("diff", ("diff_L2", "diff_H1"), "error", False, ("data",)),  # successive differences
)
MEASURE_KEYS = tuple(m.key for m in MEASURES)
# the error columns against an exact solution, then against a reference solution (data-only scenes) and the
# successive differences: the columns an `expect:` block may name
ERROR_NORMS = ("L2", "H1") + tuple(c for m in MEASURES if m.kind == "error" and m.contact for c in m.columns)
REFERENCE_NORMS = tuple(f"{norm}_ref" for norm in ERROR_NORMS) + next(m.columns for m in MEASURES if m.key == "diff")


def defaults(scene):
    """The measure keys a scene ("exact" or "data") takes unless verification.measures says otherwise."""
    return tuple(m.key for m in MEASURES if scene in m.default)
