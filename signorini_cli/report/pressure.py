"""The contact pressure profile: p_h = (1/ε)[w_h]_+^α along Γ_C, one curve per level, with the exact pressure
where it is known (a manufactured u_ex: (1/ε)[w_ex]_+^α; a Hertz contact: p0 (1 − (x/a)²)^(1/2) with Hertz's a,
p0 of the finest level's force) — x along a 2-D face, the distance r from the contact set's centre in 3-D."""
import numpy as np

from . import plots


def write(data, folder, width=None):
    """pressure.png and .pdf in `folder` from (profile rows, rate rows); the paths written."""
    profile, rates = data
    with plots.styled():
        return plots.save(figure(profile, rates, width or plots.WIDTH_PT), folder, "pressure")


def figure(profile, rates, width):
    """One panel: a curve per level (its N in the legend), the exact or Hertz pressure in black."""
    levels = sorted({row["level"] for row in profile})
    position = "r" if "r" in profile[0] else "x"
    exact = exact_curve([row for row in profile if row["level"] == levels[-1]], rates, levels[-1], position)
    fig, (ax,) = plots.panels(1, width, -(-(len(levels) + (exact is not None)) // 2), "")
    by_level = {row["level"]: row for row in rates}
    for k, level in enumerate(levels):
        mine = [row for row in profile if row["level"] == level]
        style = plots.curve_style(k)
        ax.plot([r[position] for r in mine], [r["pressure"] for r in mine], color=style["color"],
                linestyle=style["linestyle"] if position == "x" else "none", marker=style["marker"],
                markersize=2, linewidth=0.8,
                label=f"N = {by_level[level]['N']}" if level in by_level else f"level {level}")
    if exact is not None:
        ax.plot(*exact, color="black", linewidth=1.0, label="exact" if "pressure_exact" in profile[0] else "Hertz")
    ax.set_xlabel(r"distance $r$ from the contact centre" if position == "r" else r"$x$ along $\Gamma_C$")
    ax.set_ylabel(r"contact pressure $p_h$")
    _zoom(ax, [r[position] for r in profile if r["pressure"] > 0], [r[position] for r in profile], position == "r")
    plots._legend_below(ax, ncol=2)
    plots._finish(fig, [ax])
    return fig


def exact_curve(finest, rates, level, position):
    """(positions, p) of the exact pressure: the finest level's pressure_exact, or Hertz's profile from its rate
    row (half_width_hertz a, peak_pressure_hertz p0) centred on its contact set; None without either."""
    if "pressure_exact" in finest[0]:
        return [r[position] for r in finest], [r["pressure_exact"] for r in finest]
    row = next((r for r in rates if r["level"] == level), {})
    a, p0 = row.get("half_width_hertz"), row.get("peak_pressure_hertz")
    touching = [r[position] for r in finest if r["pressure"] > 0]
    if not a or not p0 or not touching:
        return None
    t = np.linspace(0 if position == "r" else -1, 1, 201)
    centre = 0.0 if position == "r" else (min(touching) + max(touching)) / 2
    return centre + a * t, p0 * np.sqrt(np.clip(1 - t**2, 0, None))


def _zoom(ax, touching, everywhere, radial):
    """x limits around the contact set (a quarter of its extent beyond each end; from r = 0 in a radial plot)."""
    if not touching:
        return
    low, high = 0.0 if radial else min(touching), max(touching)
    margin = (high - low) / 4 or (max(everywhere) - min(everywhere)) / 20
    ax.set_xlim(0.0 if radial else max(low - margin, min(everywhere)), min(high + margin, max(everywhere)))
