"""The study's CSV tables (rates.csv, summary.csv, sweep.csv, ...), written and read here alone."""
import csv
import io


class Damaged(OSError):
    """A CSV table that cannot be read (not text, rows cut short): bad input for report and compare."""


def text(rows, columns=None):
    """The table as CSV: floats in full precision, empty cells for missing values, true/false; `columns`
    defaults to every row's keys, in order of appearance (rows lacking a column leave it empty)."""
    if not rows and columns is None:
        return ""
    out = io.StringIO()
    columns = columns or list(dict.fromkeys(key for row in rows for key in row))
    writer = csv.DictWriter(out, fieldnames=list(columns), lineterminator="\n", restval="")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _cell(v) for k, v in row.items()})
    return out.getvalue()


def _cell(value):
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return value


def read(path):
    """The rows of a CSV table with typed cells (int, float, true/false as bool, empty as None); Damaged
    when it is not one."""
    try:
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            raw = list(reader)
    except (UnicodeDecodeError, csv.Error) as err:
        raise Damaged(f"{path}: damaged, not a CSV table ({str(err).splitlines()[0]})") from None
    for k, row in enumerate(raw):
        if None in row or None in row.values():  # more or fewer fields than the header: cut short
            raise Damaged(f"{path}: damaged, row {k + 1} does not have the header's {len(reader.fieldnames)} fields")
    return [{key: value(cell) for key, cell in row.items()} for row in raw]


def value(cell):
    """A CSV cell as the Python value it was written from."""
    if cell == "":
        return None
    if cell in ("true", "false"):
        return cell == "true"
    for kind in (int, float):
        try:
            return kind(cell)
        except ValueError:
            pass
    return cell
