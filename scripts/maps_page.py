"""docs/maps.md from the runs of configs/maps/ (`make maps`): each map's figures, its table and what it shows.

    python scripts/maps_page.py CONFIG.yaml ... [--output RESULTS] [--out docs/maps.md]
reads each map's map.csv and the study.h5 of its points; every number on the page comes from them."""
import argparse
import sys
from pathlib import Path

import provenance
from signorini_cli import config
from signorini_cli.record import csvfile
from signorini_cli.report import maps, plots

TOLERANCE = 0.1  # verification.tolerance's default: a fitted rate within 0.1 of the proven one holds it

HEADER = """# Rate maps: where the proven rates stop holding

{provenance}

Each map below is one `signorini run` of a config in `configs/maps/` (`study_type: map`): every point is a
complete refinement study in `results/<map>/points/<k>/`, run on 2 ranks as two groups of one rank. A heat
map colours the fitted rate minus the paper's proven rate (blue above, red below, white on it; ±1 saturates),
writes the fitted rate in the cell, marks the verdict (o agrees, ^ exceeds, v below, x inconclusive) and
greys the points the paper does not cover. Rates are fitted over the last three levels (`verification.fit_levels`);
the rate is the plain slope of log e against log h; where the proven rate carries |ln h| (d = 2, alpha > 2) the
fit of e/|ln h| is given beside it. The problems are the manufactured ones of the shipped studies (u = sin(2 pi x)(1-y)^2
in 2-D, sin(2 pi x) sin(pi y)(1-z)^2 in 3-D, contact on y = 0 resp. z = 0, data g making u exact at every eps):
a map says where a rate holds on these problems, not in general.
How to read the verdicts, and how to run a map of your own: docs/guide/maps.md.
"""


def main(argv=None):
    parser = argparse.ArgumentParser(prog="scripts/maps_page.py", description=__doc__.split("\n")[0])
    parser.add_argument("configs", nargs="+", help="the configs/maps maps, already run")
    parser.add_argument("--output", help="the results folder the maps were run with (overrides output.dir)")
    parser.add_argument("--out", default="docs/maps.md", help="the page to write; figures go to maps/ beside it")
    args = parser.parse_args(argv)
    out = Path(args.out)
    figures = out.parent / "maps"
    figures.mkdir(parents=True, exist_ok=True)
    found = [(path, config.load(path, [f"output.dir={args.output}"] if args.output else [])) for path in args.configs]
    points = [s.output_dir for _, cfg in found for s in cfg.map.studies]
    sections = [HEADER.format(provenance=provenance.line("maps", points))]
    for path, cfg in found:
        sections.append(section(path, cfg, read_rows(cfg), figures, out.parent))
    out.write_text("\n".join(sections))
    print(f"wrote {out}", file=sys.stderr)


def read_rows(cfg):
    """map.csv's rows, cells typed as written (csvfile)."""
    return csvfile.read(cfg.output_dir / maps.MAP_FILE)


def section(path, cfg, rows, figures, docs):
    """A map's heading, config, figures, what it shows and its table."""
    varied = cfg.map.varied
    lines = [f"## {cfg.description}", "",
             f"`{path}`: {len(rows)} points ({' × '.join(f'{k} {len(v)}' for k, v in cfg.map.grid.items())}), "
             f"N = {', '.join(map(str, cfg.mesh.levels))}, d = {cfg.dimension}; "
             f"{sum(r['time_s'] for r in rows):.0f} s of solves in all; "
             f"{sum(r['converged'] is True for r in rows)} of {len(rows)} points converged on every level.", ""]
    for name, draw in figure_set(cfg, varied):
        target = figures / f"{cfg.study}-{name}.png"
        with plots.styled():
            draw(rows).savefig(target)
        lines += [f"![{cfg.study} {name}]({target.relative_to(docs)})", ""]
    lines += ["What it shows:", ""] + [f"- {line}" for line in FINDINGS.get(cfg.study, generic)(rows)] + [""]
    lines += ["<details><summary>The map's table (map.md)</summary>", "",
              maps.markdown_table(rows, varied, maps.shown_norms(maps.rate_map.norms_of(rows))), "</details>", ""]
    return "\n".join(lines)


def figure_set(cfg, varied):
    """(name, draw(rows)) of the figures shown: the L2 heat map of the first two keys, the L2 (and H1) rate
    against the first key (the |ln h| map: against alpha, plain and log fits side by side)."""
    a, b = varied[0], varied[1]
    shown = [("heat-L2", lambda rows: maps.heat_map(rows, "L2", a, b, list(varied[2:])))]
    if cfg.study == "map-square-log-alpha":
        return shown + [("rate-L2", lambda rows: maps.rate_lines(rows, "L2", "alpha", ["epsilon.theta"]))]
    shown.append(("rate-L2", lambda rows: maps.rate_lines(rows, "L2", a, [k for k in varied if k != a])))
    if cfg.study == "map-square-power-p":
        shown.append(("rate-H1", lambda rows: maps.rate_lines(rows, "H1", a, [k for k in varied if k != a])))
    return shown


def _range(values):
    values = [v for v in values if v is not None]
    return f"{min(values):.2f}–{max(values):.2f}" if values else "-"


def _values(rows, key):
    """The rows' values of `key`, as numbers are written on the page."""
    return ", ".join(f"{r[key]:g}" for r in rows)


def _verdicts(rows, norm="L2"):
    """The rows' verdicts of `norm`, each once, in order."""
    return ", ".join(sorted({r[f"verdict_{norm}"] for r in rows}))


def _by(rows, key):
    groups = {}
    for row in rows:
        groups.setdefault(row[key], []).append(row)
    return groups


def theta_alpha(rows):
    """Map (a): per alpha, the theta at which the L2 rate holds 2 - TOLERANCE, and its range."""
    lines = []
    for alpha, group in _by(rows, "alpha").items():
        rates = [(r["epsilon.theta"], r["rate_L2"]) for r in group]
        holding = [theta for theta, rate in rates if rate is not None and rate >= 2 - TOLERANCE]
        where = (f"at every theta from {min(holding):g} to {max(holding):g}" if len(holding) == len(rates)
                 else f"at theta = {', '.join(f'{t:g}' for t in holding) or 'none'} of {len(rates)}")
        logs = [r["rate_L2_log"] for r in group if r.get("rate_L2_log") is not None]
        fit = f"fitted L2 rate {_range(r for _, r in rates)}" + (f" (fit of e/|ln h| {_range(logs)})" if logs else "")
        lines.append(f"alpha = {alpha}: {fit}; >= {2 - TOLERANCE:g} {where} (verdicts: {_verdicts(group)}).")
    return lines


def power_p(rows):
    """Map (b): per alpha and p, the L2 and H1 rates; outside h <~ eps (p > 1) the verdicts say not covered."""
    lines = []
    for alpha, group in _by(rows, "alpha").items():
        inside = [r for r in group if r["epsilon.exponent"] <= 1]
        outside = [r for r in group if r["epsilon.exponent"] > 1]
        lines.append(f"alpha = {alpha}: p <= 1: L2 {_range(r['rate_L2'] for r in inside)}, H1 "
                     f"{_range(r['rate_H1'] for r in inside)}; p > 1 (outside h <~ eps): L2 "
                     f"{_range(r['rate_L2'] for r in outside)}, H1 {_range(r['rate_H1'] for r in outside)}.")
    return lines


def cube(rows):
    """Map (c): the 3-D L2 rate against 8/5 and 2, per exponent."""
    lines = []
    for p, group in _by(rows, "epsilon.exponent").items():
        proven = sorted({f"{r['proven_L2']:g}" if r["proven_L2"] is not None else "none" for r in group})
        lines.append(f"p = {p}: fitted L2 rate {_range(r['rate_L2'] for r in group)} over theta = "
                     f"{_values(group, 'epsilon.theta')} (proven: {', '.join(proven)}; verdicts: "
                     f"{_verdicts(group)}).")
    return lines


def log_alpha(rows):
    """Map (d): the plain fit of e and the fit of e/|ln h|, side by side, per alpha."""
    lines = []
    for alpha, group in _by(rows, "alpha").items():
        lines.append(f"alpha = {alpha}: L2 plain fit of e {_range(r['rate_L2'] for r in group)}, fit of e/|ln h| "
                     f"{_range(r.get('rate_L2_log') for r in group)} (theta = "
                     f"{_values(group, 'epsilon.theta')}; verdicts: "
                     f"{_verdicts(group)}).")
    return lines


def generic(rows):
    """Any other map: the range of the fitted L2 and H1 rates."""
    return [f"fitted L2 rate {_range(r.get('rate_L2') for r in rows)}, H1 "
            f"{_range(r.get('rate_H1') for r in rows)} over its {len(rows)} points."]


FINDINGS = {"map-square-theta-alpha": theta_alpha, "map-square-power-p": power_p,
            "map-cube-alpha2-theta-p": cube, "map-square-log-alpha": log_alpha}


if __name__ == "__main__":
    main()
