"""docs/geometries.md from the configs/gmsh studies run serially and on 2 ranks (`make geometries`).

usage: python scripts/geometries_page.py SERIAL_DIR MPI_DIR CONFIG... > docs/geometries.md"""
import math
import sys
from pathlib import Path


import provenance
from signorini_cli import config
from signorini_cli.analysis import rates
from signorini_cli.record import csvfile

# |Γ_C| of the exact domain, by geometry (or .msh file stem): the figure the discrete |Γ_C,h| approaches
EXACT_GAMMA_C = {"unit_square": 1.0, "l_shape": 1.0, "unit_cube": 1.0, "half_disk": math.pi,
                 "half_ball": 2 * math.pi, "quarter_annulus": math.pi / 2}


def rows(folder, cfg):
    return csvfile.read(Path(folder) / cfg.study / "rates.csv")


def exact_gamma_c(cfg):
    return EXACT_GAMMA_C.get(Path(cfg.mesh.geometry or cfg.mesh.path[0]).stem)


def fitted(rows, column):
    """Slope of log(column) against log(h) over the last rates.FIT_LEVELS levels, or None."""
    last = rows[-rates.FIT_LEVELS:]
    if any(r.get(column) is not None and float(r[column]) <= 0 for r in last):
        return None
    return rates.slope([float(r["h"]) for r in last], [float(r[column]) if r.get(column) else None for r in last])


def gap_rates(serial, exact):
    """|Γ_C| − |Γ_C,h| per level and its rate in h (None where undefined)."""
    gaps = [exact - float(r["gamma_c_measure"]) for r in serial]
    h = [float(r["h"]) for r in serial]
    return gaps, rates.observed(h, gaps, [g > 1e-13 for g in gaps])


MESH_COLUMNS = ("h", "h_min", "gamma_c_measure", "gamma_c_quasi_uniformity")


def parallel_difference(serial, parallel, columns):
    """Largest relative difference of `columns` between the serial and the 2-rank run, and whether
    both runs had the same levels, cells and dofs."""
    diffs = [abs(float(p[c]) / float(s[c]) - 1) for s, p in zip(serial, parallel) for c in columns]
    same_mesh = all(s["N"] == p["N"] and s["dofs"] == p["dofs"] for s, p in zip(serial, parallel))
    return (max(diffs) if diffs else None), same_mesh and len(serial) == len(parallel)


def table(serial, exact):
    norms = [n for n in ("L2", "H1", "L2_ref", "H1_ref") if n in serial[0]]
    gaps, gap_rate = gap_rates(serial, exact) if exact else ([None] * len(serial), [None] * len(serial))
    head = ["level", "N", "dofs", "h", "h_min", "ε", "\\|Γ_C,h\\|", "\\|Γ_C\\| − \\|Γ_C,h\\|", "rate",
            "quasi-unif.", "Newton"]
    for n in norms:
        head += [n, f"rate {n}"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r, gap, g_rate in zip(serial, gaps, gap_rate):
        cells = [r["level"], r["N"], r["dofs"], _e(r["h"]), _e(r["h_min"]), _e(r["epsilon"]),
                 f"{float(r['gamma_c_measure']):.6f}", _e(gap), _f(g_rate),
                 f"{float(r['gamma_c_quasi_uniformity']):.3f}", r["newton_its"]]
        for n in norms:
            cells += [_e(r[n]), _f(r[f"rate_{n}"])]
        lines.append("| " + " | ".join(str(c) for c in cells) + " |")
    return lines, norms


def _e(value):
    return "–" if value in (None, "") else f"{float(value):.3e}"


def _f(value):
    return "–" if value in (None, "") else f"{float(value):.2f}"


def section(cfg, serial, parallel):
    exact = exact_gamma_c(cfg)
    lines, norms = table(serial, exact)
    out = [f"## {cfg.study}", "", f"{cfg.description}", "",
           f"Mesh: `{_mesh_text(cfg)}`, Γ_C = group `{cfg.contact}`"
           + (f", exact \\|Γ_C\\| = {exact:.6f}." if exact else "."), ""] + lines + [""]
    fits = [f"{n} {fitted(serial, n):.2f}" for n in norms if fitted(serial, n) is not None]
    if fits:
        out.append(f"Least-squares rate over the last {rates.FIT_LEVELS} levels: " + ", ".join(fits) + ".")
    mesh_diff, same = parallel_difference(serial, parallel, MESH_COLUMNS)
    out.append(f"`mpirun -n 2`: same cells and dofs on every level: {'yes' if same else 'NO'}; largest relative "
               f"difference from the serial run of h, h_min, \\|Γ_C,h\\|, quasi-uniformity: {mesh_diff:.1e}"
               + (f"; of {', '.join(norms)}: {parallel_difference(serial, parallel, norms)[0]:.1e}." if norms else
                  "."))
    if any(n.endswith("_ref") for n in norms):
        r = cfg.verification.reference_refinements
        out.append(f"`*_ref`: errors against a reference solution on the finest level refined {r} more time(s), "
                   f"at each level's ε ({cfg.verification.reference_epsilon}); the finest level's rate is the "
                   "least reliable, its reference being closest to it.")
    return out + [""]


def _in_repository(path):
    """A mesh file's path from the repository's root: the page reads the same on every checkout."""
    return str(Path(path).resolve().relative_to(Path(__file__).resolve().parents[1]))


def _mesh_text(cfg):
    m = cfg.mesh
    source = f"geometry: {m.geometry}" if m.kind == "gmsh" else f"path: {[_in_repository(p) for p in m.path]}"
    levels = f"sizes: {list(m.sizes)}" if m.kind == "gmsh" else ""
    refine = f", refine: uniform, refinements: {list(m.refinements)}" if m.refine == "uniform" else ""
    return f"kind: {m.kind}, {source}" + (f", {levels}" if levels else "") + refine


def main(argv):
    serial_dir, mpi_dir, *paths = argv
    out = ["# Studies on gmsh geometries", "",
           provenance.line("geometries", [Path(d) / config.load(p).study for d in (serial_dir, mpi_dir)
                                          for p in paths]),
           "Runs of `configs/gmsh/*.yaml`, serially and under `mpirun -n 2`. Columns: see docs/guide/meshes.md. "
           "\\|Γ_C\\| − \\|Γ_C,h\\| is the gap between the exact and the discrete contact boundary "
           "(the polygonal geometry error; its rate in h is 2 for re-meshed curved boundaries, and it is 0 or "
           "constant on straight boundaries and nested families).", ""]
    for path in paths:
        cfg = config.load(path)
        out += section(cfg, rows(serial_dir, cfg), rows(mpi_dir, cfg))
    print("\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1:])
