"""Captions of the tables that are not rate tables against h (an ε-sweep's, a total-error study's): what
their rows and columns are, in mathematics, from the study's fields."""
from . import latex

MODEL_ERROR = r"$e = \|u_{\varepsilon,h}-u_{S,h}\|$"  # compliance against discrete Signorini, one mesh
SWEEP = ("Model error " + MODEL_ERROR + r" between the compliance solution $u_{\varepsilon,h}$ and the discrete "
         r"Signorini solution $u_{S,h}$ on the finest mesh, for each $\alpha$ and $\varepsilon$, in the norms the "
         r"columns name (every mesh and norm: sweep.md); rate: "
         r"$\log(e_k/e_{k-1})/\log(\varepsilon_k/\varepsilon_{k-1})$ between successive $\varepsilon$")
FITTED = (r"Slope of $\log e$ against $\log\varepsilon$, " + MODEL_ERROR + r", fitted per mesh and $\alpha$ over "
          r"the smallest <fit> values of $\varepsilon$ (from $\varepsilon_{\max}$ to $\varepsilon_{\min}$)")
TOTAL = (r"Total error against the Signorini solution $u_S$ of compliance solutions with $\varepsilon = <eps>$, "
         r"for each $\alpha$ and $p$ (the row without them: the discrete Signorini problem), on the finest level $N$: "
         r"errors, the last rate $\log(e_k/e_{k-1})/\log(h_k/h_{k-1})$ and the slope of $\log e$ against $\log h$ "
         r"fitted over the last <fit> levels")
CAPTIONS = {"sweep": SWEEP, "fitted": FITTED, "total": TOTAL}


def of_table(name, cfg=None):
    """The caption of table `name` of a study with config `cfg` (the limit section's θ and fit)."""
    limit = getattr(cfg, "limit", None)
    theta = "" if limit is None or limit.theta == 1 else latex.constant(limit.theta)
    fit = "the last" if limit is None else limit.fit_last
    if name not in CAPTIONS:
        return "Table " + latex.escape(name)
    return CAPTIONS[name].replace("<eps>", f"{theta}h^p").replace("<fit>", str(fit))
