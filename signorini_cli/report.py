"""Human-readable output: the rate table on the terminal."""

FORMATS = {"h": ".4e", "epsilon": ".3e", "time_s": ".2f"}
SHOWN = ("level", "N", "h", "dofs", "epsilon", "converged", "newton_its")


def format_table(rows):
    """The rate table, right-aligned: errors .3e, rates .2f, '-' where a rate is undefined."""
    if not rows:
        return "(no levels)"
    columns = [c for c in rows[0] if c in SHOWN or _is_error(c, rows[0]) or c.startswith("rate_")]
    columns.append("time_s")
    cells = [[_format(column, row.get(column)) for column in columns] for row in rows]
    widths = [max(len(column), *(len(line[i]) for line in cells)) for i, column in enumerate(columns)]
    lines = ["  ".join(column.rjust(w) for column, w in zip(columns, widths))]
    lines += ["  ".join(cell.rjust(w) for cell, w in zip(line, widths)) for line in cells]
    failed = [row for row in rows if not row["converged"]]
    lines += [f"level {row['level']} (N={row['N']}) did not converge: {row['reason']}" for row in failed]
    return "\n".join(lines)


def _is_error(column, row):
    return f"rate_{column}" in row


def _format(column, value):
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if column.startswith("rate_"):
        return f"{value:.2f}"
    if column in FORMATS:
        return f"{value:{FORMATS[column]}}"
    if isinstance(value, float):
        return f"{value:.3e}"
    return str(value)
