"""LaTeX for rate tables: escaped text, numbers as m×10^k, the config's expressions typeset, and a
table layout chosen to fit \\textwidth (font size, stacked parts) from estimated column widths."""
import ast
import math
import re

TEXTWIDTH_PT = 345.0  # \textwidth of \documentclass{article} at 10 pt, the narrowest common page
FILL = 0.95  # estimates are of Computer Modern's widths; 5 % kept for what they miss
SIZES = (("", 1.0), (r"\small", 0.9), (r"\footnotesize", 0.8))  # font sizes tried, with their scale
TABCOLSEP_PT = 3.0
MAX_TEXT = 40  # characters of a text cell (a CSV's reason or a user's column): longer ones are cut

# plain text in LaTeX: the specials escaped, the usual Unicode as math, anything else as "?"
TEX_TEXT = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
            "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
            "<": r"\textless{}", ">": r"\textgreater{}", "|": r"\textbar{}",
            "α": r"$\alpha$", "ε": r"$\varepsilon$", "θ": r"$\theta$", "Γ": r"$\Gamma$", "π": r"$\pi$",
            "δ": r"$\delta$", "Ω": r"$\Omega$", "≥": r"$\geq$", "≤": r"$\leq$", "→": r"$\to$", "−": "-",
            "×": r"$\times$", "²": r"$^2$", "³": r"$^3$", "·": r"$\cdot$", "–": "--", "—": "---"}


def escape(text):
    """`text` as LaTeX text mode: nothing in it can run a command (\\input, \\write18 ...)."""
    return "".join(TEX_TEXT.get(char, char if char.isascii() and char.isprintable() else "?")
                   for char in str(text))


def label(*parts):
    """A \\label key from free text: letters, digits and -.: kept, anything else as -."""
    return "tab:" + "-".join(re.sub(r"[^A-Za-z0-9.:-]+", "-", part).strip("-") for part in parts if part)


def number(value, digits):
    """$2.303\\times10^{-2}$ (no package needed; 10^{0} too: one format per column), inf and nan as text."""
    if not math.isfinite(value):
        return escape(str(value))
    if value == 0:
        return "$0$"
    mantissa, exponent = f"{value:.{digits}e}".split("e")
    return rf"${mantissa}\times10^{{{int(exponent)}}}$"


def rate(value):
    """A rate .2f; a negative one in math mode (a minus sign, not a hyphen)."""
    return f"${value:.2f}$" if value < 0 else f"{value:.2f}"


def constant(value):
    """A number in a formula: 2, 0.5, 10^{-3}, 2.5\\times10^{4}."""
    if float(value).is_integer() and abs(value) < 1e6:
        return str(int(value))
    text = f"{value:.6g}"
    if "e" not in text:
        return text
    mantissa, exponent = text.split("e")
    power = f"10^{{{int(exponent)}}}"
    return power if mantissa == "1" else rf"{mantissa}\times{power}"


# --- the config's expressions (config/expressions.py's grammar) typeset -----------------------------

SYMBOLS = {"pi": r"\pi", "e": "e", "eps": r"\varepsilon", "alpha": r"\alpha", "theta": r"\theta",
           "delta": r"\delta"}
FUNCTIONS = {"sin": r"\sin", "cos": r"\cos", "tan": r"\tan", "exp": r"\exp", "log": r"\log", "tanh": r"\tanh",
             "sinh": r"\sinh", "cosh": r"\cosh", "asin": r"\arcsin", "acos": r"\arccos", "atan": r"\arctan",
             "atan2": r"\operatorname{atan2}", "min": r"\min", "max": r"\max"}
SUM, PRODUCT, UNARY, POWER, ATOM = range(5)  # binding strength


def expression(tree):
    """The LaTeX math of an expression tree of the config's grammar (numbers, + - * / **, names,
    the whitelisted functions): 2*pi*x -> 2 \\pi x, (1-y)**2 -> (1 - y)^{2}, a/b -> \\frac{a}{b}."""
    return _tex(tree)[0]


def _tex(node):
    """(LaTeX, binding strength) of `node`."""
    if isinstance(node, ast.Constant):
        return constant(node.value), ATOM if node.value >= 0 else UNARY
    if isinstance(node, ast.Name):
        return SYMBOLS.get(node.id, escape(node.id)), ATOM
    if isinstance(node, ast.UnaryOp):
        text = _wrapped(node.operand, POWER if isinstance(node.op, ast.USub) else UNARY)
        return ("-" if isinstance(node.op, ast.USub) else "+") + text, UNARY
    if isinstance(node, ast.Call):
        argument = ", ".join(_tex(arg)[0] for arg in node.args)  # atan2(y, x), min(a, b): two
        if node.func.id == "sqrt":
            return rf"\sqrt{{{argument}}}", ATOM
        if node.func.id == "abs":
            return rf"|{argument}|", ATOM
        return rf"{FUNCTIONS[node.func.id]}({argument})", POWER  # a factor; as a base: (\sin(x))^{2}
    return _binary(node)


def _binary(node):
    if isinstance(node.op, ast.Div):
        return rf"\frac{{{_tex(node.left)[0]}}}{{{_tex(node.right)[0]}}}", ATOM
    if isinstance(node.op, ast.Pow):
        return f"{_wrapped(node.left, ATOM)}^{{{_tex(node.right)[0]}}}", POWER
    if isinstance(node.op, ast.Mult):
        left, right = _wrapped(node.left, PRODUCT), _wrapped(node.right, UNARY + 1)
        joint = r" \cdot " if right[0].isdigit() else " "  # 2 \cdot 3, but 2 \pi x
        return left + joint + right, PRODUCT
    left = _tex(node.left)[0]
    right = _wrapped(node.right, PRODUCT if isinstance(node.op, ast.Sub) else SUM)
    return f"{left} {'-' if isinstance(node.op, ast.Sub) else '+'} {right}", SUM


def _wrapped(node, strength):
    """`node` in parentheses unless it binds at least as strongly as `strength`."""
    text, own = _tex(node)
    return text if own >= strength else f"({text})"


# --- width estimates (Computer Modern at 10 pt; a font size scales them) ------------------------------

GLYPH_PT = {**dict.fromkeys("0123456789", 5.0), ".": 2.78, ",": 2.78, "-": 3.33, " ": 3.33, "(": 3.89,
            ")": 3.89, "?": 4.72, "/": 5.0, ":": 2.78, "+": 7.78, "=": 7.78}


def text_width(text):
    """Estimated width (pt, 10 pt font) of plain text: capitals and wide letters counted generously."""
    return sum(GLYPH_PT.get(c, 7.5 if c.isupper() or c in "mw" else 5.3) for c in text)


SCRIPT = re.compile(r"[_^](\{[^{}]*(?:\{[^{}]*\}[^{}]*)*\}|\\[A-Za-z]+|[A-Za-z0-9])")  # at 7 pt (0.8: margin)


def cell_width(cell):
    """Estimated width of a cell this module wrote: a number, a rate, an integer or escaped text."""
    match = re.fullmatch(r"\$(-?[\d.]+)(?:\\times10\^\{(-?\d+)\})?\$", cell)
    if match:  # mantissa, then × (with its spacing) 10 and the exponent at 7 pt
        mantissa, exponent = match.groups()
        power = 12.2 + 10.0 + 0.7 * text_width(exponent) + (4.4 if "-" in exponent else 0.0) if exponent else 0
        return text_width(mantissa) + (4.4 if mantissa.startswith("-") else 0.0) + power
    return _plain_width(SCRIPT.sub("", cell)) + 0.8 * sum(map(_plain_width, SCRIPT.findall(cell)))


def _plain_width(cell):
    plain = re.sub(r"\\(texttt|mathrm|textit|emph|max|min|log)\b", "", cell)  # fonts: their argument counts
    plain = re.sub(r"\\[A-Za-z]+(\{\})?|\\.", "x", plain)  # a symbol or an escaped character: one glyph
    return text_width(re.sub(r"[{}$^_]", "", plain))


# --- the table ------------------------------------------------------------------------------------

def table(columns, groups, caption, key, rows_count, align=None):
    """A `table` float (booktabs) of `columns` [(header, cells)] whose trailing columns pair up under
    `groups` [(title, 2)] super-columns; laid out to fit \\textwidth: at the largest font size that
    fits, else split by norms: stacked tabulars that repeat the columns before them, each sized alike;
    `align`: the columns' alignment (default: all right)."""
    size, parts = _plan(_units(columns, groups))
    if size == "" and len(parts) == 1:
        why = "fits \\textwidth at the normal size"
    else:
        stacked = f", as {len(parts)} stacked parts that repeat the first column" if len(parts) > 1 else ""
        why = (f"{size or 'normal size'}{stacked}: the columns do not fit {TEXTWIDTH_PT:g}pt otherwise "
               "(widths estimated from Computer Modern's)")
    lines = [f"% layout: {why}", r"\begin{table}", r"\centering", r"\caption{" + caption + "}",
             rf"\label{{{key}}}"] + ([size] if size else [])  # the caption at the text's size
    lines.append(rf"\setlength{{\tabcolsep}}{{{TABCOLSEP_PT:g}pt}}")
    letters = {id(column): letter for column, letter in zip(columns, align or "r" * len(columns))}
    for k, part in enumerate(parts):
        if k:
            lines.append(r"\par\medskip")
        lines += _tabular(part, rows_count, letters)
    return "\n".join(lines + [r"\end{table}"]) + "\n"


def _units(columns, groups):
    """What stays together: a single column (title None) or a super-column's columns."""
    n_single = len(columns) - sum(n for _, n in groups)
    units, at = [(None, [column]) for column in columns[:n_single]], n_single
    for title, n in groups:
        units.append((title, columns[at:at + n]))
        at += n
    return units


def _unit_width(unit):
    """Estimated width (pt, 10 pt font) of a unit with its column separations."""
    title, columns = unit
    widths = [max([cell_width(header)] + [cell_width(c) for c in cells]) + 2 * TABCOLSEP_PT
              for header, cells in columns]
    return max(sum(widths), cell_width(title) + 2 * TABCOLSEP_PT) if title else sum(widths)


def _fits(width, scale):
    return width * scale <= FILL * TEXTWIDTH_PT


def _plan(units):
    """(font size command, [parts of units]): the largest size at which the whole table fits, else the
    fewest stacked parts at \\small (at \\footnotesize when even one unit is too wide for \\small)."""
    widths = [_unit_width(u) for u in units]
    for size, scale in SIZES:
        if _fits(sum(widths), scale):
            return size, [units]
    n_key = next((k for k, (title, _) in enumerate(units) if title), 1)  # split by norms: the rest repeated
    if not all(_fits(sum(widths[:n_key]) + w, SIZES[-1][1]) for w in widths[n_key:]):
        n_key = 1  # too many columns before the norms to repeat: the first alone
    key = (None, [c for _, cols in units[:n_key] for c in cols])
    units, widths = [key] + units[n_key:], [sum(widths[:n_key])] + widths[n_key:]
    rest = list(zip(units[1:], widths[1:]))
    for size, scale in SIZES[1:]:
        if all(_fits(widths[0] + w, scale) for _, w in rest):
            break
    parts, width = [[key]], widths[0]
    for unit, w in rest:
        if len(parts[-1]) > 1 and not _fits(width + w, scale):
            parts, width = parts + [[key]], widths[0]
        parts[-1].append(unit)
        width += w
    return size, parts


def _tabular(units, rows_count, letters):
    columns = [column for _, cols in units for column in cols]
    lines = [r"\begin{tabular}{" + "".join(letters[id(c)] for c in columns) + "}", r"\toprule"]
    if any(title for title, _ in units):
        head, rules, at = [], [], 1
        for title, cols in units:
            head.append(rf"\multicolumn{{{len(cols)}}}{{c}}{{{title}}}" if title else " & " * (len(cols) - 1))
            if title:
                rules.append(rf"\cmidrule(lr){{{at}-{at + len(cols) - 1}}}")
            at += len(cols)
        lines += [" & ".join(head) + r" \\", " ".join(rules)]
    lines += [" & ".join(header for header, _ in columns) + r" \\", r"\midrule"]
    lines += [" & ".join(cells[k] for _, cells in columns) + r" \\" for k in range(rows_count)]
    return lines + [r"\bottomrule", r"\end{tabular}"]
