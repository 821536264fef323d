"""The report's tables: each one drawn as HTML in the page and written as CSV beside it.

A `Table` holds its values in the units its header names (GPa, Hz, %: the page never mixes Pa and
GPa), unformatted; `Table.html` formats them for reading, `Table.csv` keeps them at full precision,
so that a spreadsheet gets the numbers the page shows. A cell is a str, an int, a float (NaN or None
shown as "-"), or an interval ``(low, high)`` (or None), which the CSV splits into two columns.

`Tables` collects the tables of one page in order; the command writes each as
``<CSV_PREFIX><name>.csv`` beside ``index.html`` through its output set (`workbench.io.outputs`),
and the page links each file. `declared_files` lists every name a command may write, since an
output set is declared before the work starts. Neither pandas nor matplotlib here.
"""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from workbench.io.outputs import csv_text

__all__ = ["CSV_PREFIX", "Table", "Tables", "csv_name", "declared_files", "TABLE_KEYS", "MAX_STUDIES",
           "MAX_PREDICTIONS"]

# The CSV files sit beside index.html: an output set (workbench.io.outputs.OutputSet) writes plain
# files of its directory, not sub-directories, so "tables/<name>.csv" is spelled "tables_<name>.csv".
CSV_PREFIX = "tables_"

# Every table key a page may hold; a study's and a prediction's tables are numbered (1_joints, p1_band)
STUDY_TABLE_KEYS = ("factors", "design", "modes", "nominal", "joints", "moments", "posterior", "accuracy",
                    "mac", "shapes")
PREDICTION_TABLE_KEYS = ("sources", "frequencies")
RUN_TABLE_KEYS = ("summary", "steps")
DIAGNOSIS_TABLE_KEYS = ("summary", "baseline", "localisation", "candidates")
TABLE_KEYS = {"study": STUDY_TABLE_KEYS, "prediction": PREDICTION_TABLE_KEYS, "run": RUN_TABLE_KEYS,
              "diagnosis": DIAGNOSIS_TABLE_KEYS}
MAX_STUDIES = 4  # a report holds one study, the demo two: room to spare
MAX_PREDICTIONS = 4

Cell = object


def csv_name(name: str) -> str:
    """The file name of table ``name`` beside the page."""
    return f"{CSV_PREFIX}{name}.csv"


def declared_files(page: str) -> tuple[str, ...]:
    """Every CSV file a page of kind ``page`` ("report" or "diagnosis") may write, for the output set."""
    if page == "diagnosis":
        return tuple(csv_name(k) for k in DIAGNOSIS_TABLE_KEYS)
    names = [*RUN_TABLE_KEYS]
    names += [f"{s}_{k}" for s in range(1, MAX_STUDIES + 1) for k in STUDY_TABLE_KEYS]
    names += [f"p{p}_{k}" for p in range(1, MAX_PREDICTIONS + 1) for k in PREDICTION_TABLE_KEYS]
    return tuple(csv_name(n) for n in names)


def _e(value: object) -> str:
    return html.escape(str(value), quote=True)


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _text(value: Cell, spec: str) -> str:
    """One cell as the page shows it."""
    if value is None:
        return "-"
    if isinstance(value, tuple):
        return f"[{_text(value[0], spec)}, {_text(value[1], spec)}]"
    if isinstance(value, float) or (_is_number(value) and spec):
        v = float(value)  # type: ignore[arg-type]
        return "-" if not math.isfinite(v) else format(v, spec or ".4g")
    return str(value)


def _split_header(name: str) -> tuple[str, str]:
    """``"E 95 % interval (GPa)"`` -> ``("E 95 % interval low (GPa)", "E 95 % interval high (GPa)")``."""
    head, unit = (name[:name.rindex(" (")], name[name.rindex(" ("):]) if name.endswith(")") and " (" in name \
        else (name, "")
    return f"{head} low{unit}", f"{head} high{unit}"


def _csv_value(value: Cell) -> object:
    if value is None:
        return ""
    if isinstance(value, float) and not math.isfinite(value):
        return ""
    if hasattr(value, "item") and not isinstance(value, (str, tuple)):  # numpy scalars
        return value.item()
    return value


@dataclass(frozen=True)
class Table:
    """One table of a page.

    Attributes
    ----------
    name : the CSV file's stem (`csv_name`).
    header : column headers, each with its unit in parentheses where the column has one.
    rows : the values, in the header's units (intervals as ``(low, high)`` tuples).
    formats : per column, the format spec of its numbers on the page ("" for text and counts).
    left : the first ``left`` columns are text (left-aligned); wrap : the last column's text wraps.
    intervals : per column, True where the cells are intervals (two CSV columns).
    """

    name: str
    header: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]
    formats: tuple[str, ...] = ()
    left: int = 1
    wrap: bool = False
    intervals: tuple[bool, ...] = field(default=())

    def __post_init__(self) -> None:
        n = len(self.header)
        formats = self.formats or ("",) * n
        if len(formats) != n:
            raise ValueError(f"table {self.name}: {len(formats)} formats for {n} columns")
        bad = [r for r in self.rows if len(r) != n]
        if bad:
            raise ValueError(f"table {self.name}: a row of {len(bad[0])} cells under {n} headers")
        object.__setattr__(self, "formats", tuple(formats))
        object.__setattr__(self, "rows", tuple(tuple(r) for r in self.rows))
        spans = tuple(any(isinstance(r[i], tuple) for r in self.rows) for i in range(n))
        object.__setattr__(self, "intervals", spans)

    def html(self, link: bool = True) -> str:
        """The table as escaped HTML, with a link to its CSV file below it when ``link``."""
        n = len(self.header)

        def cell(tag: str, i: int, value: str) -> str:
            cls = "l w" if self.wrap and i == n - 1 else "l" if i < self.left else ""
            return f'<{tag} class="{cls}">{_e(value)}</{tag}>' if cls else f"<{tag}>{_e(value)}</{tag}>"

        head = "".join(cell("th", i, h) for i, h in enumerate(self.header))
        body = "".join("<tr>" + "".join(cell("td", i, _text(c, self.formats[i])) for i, c in enumerate(row))
                       + "</tr>" for row in self.rows)
        csv = (f'<p class="csv"><a href="{_e(csv_name(self.name))}">{_e(csv_name(self.name))}</a> '
               "(the table as CSV, full precision)</p>" if link else "")
        return (f'<div class="scroll"><table data-table="{_e(self.name)}"><thead><tr>{head}</tr></thead>'
                f"<tbody>{body}</tbody></table></div>{csv}")

    def csv(self) -> str:
        """The table as CSV text: numbers at full precision, intervals as two columns, empty where absent."""
        header: list[str] = []
        for name, span in zip(self.header, self.intervals):
            header += list(_split_header(name)) if span else [name]
        rows = []
        for row in self.rows:
            out: list[object] = []
            for value, span in zip(row, self.intervals):
                if span:
                    pair = value if isinstance(value, tuple) else (None, None)
                    out += [_csv_value(pair[0]), _csv_value(pair[1])]
                else:
                    out.append(_csv_value(value))
            rows.append(out)
        return csv_text(header, rows)


class Tables:
    """The tables of one page, in order of appearance; `add` returns the table's HTML."""

    def __init__(self) -> None:
        self.items: list[Table] = []

    def add(self, name: str, header: Sequence[str], rows: Iterable[Sequence[Cell]], formats: Sequence[str] = (),
            left: int = 1, wrap: bool = False) -> str:
        """Register a table (`Table`) and return its HTML with the link to its CSV file."""
        if any(t.name == name for t in self.items):
            raise ValueError(f"table {name}: two tables of one page share the name")
        table = Table(name, tuple(header), tuple(tuple(r) for r in rows), tuple(formats), left, wrap)
        self.items.append(table)
        return table.html()

    def files(self) -> dict[str, str]:
        """CSV file name -> text, one per table."""
        return {csv_name(t.name): t.csv() for t in self.items}
