"""A study's tables (a row per job; a row per paired difference) as CSV or Parquet bytes, column
types kept in Parquet."""

from __future__ import annotations

import csv
import io
import numbers
from collections.abc import Sequence
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from nanonav.studies.report import DIFFERENCE_COLUMNS, METRICS, WALL_CLOCK_COLUMN

PARQUET_MEDIA_TYPE = "application/vnd.apache.parquet"
# Columns of whole numbers in either table, typed so even when every cell is empty.
COUNTS = ("job_id", "seed", "n", "holm_comparisons")


def to_csv(columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> str:
    """The table as CSV; an empty cell is a missing value (a job that did not succeed)."""
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row.get(k) is None else _cell(row[k])) for k in columns})
    return out.getvalue()


def _cell(value: Any) -> Any:
    return repr(value) if isinstance(value, float) else value


def to_parquet(columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> bytes:
    """The table as a Parquet file: ids, seeds and counts int64, metrics and statistics float64
    (null when missing), grid values as their own type when a column has one, else strings."""
    arrays = [_column(k, rows) for k in columns]
    table = pa.Table.from_arrays(arrays, names=list(columns))
    out = io.BytesIO()
    pq.write_table(table, out)
    return out.getvalue()


def _column(column: str, rows: Sequence[dict[str, Any]]) -> pa.Array:
    kind = _type(column, rows)
    values = [row.get(column) for row in rows]
    if kind == pa.string():
        values = [None if v is None else str(v) for v in values]
    return pa.array(values, type=kind)


def _type(column: str, rows: Sequence[dict[str, Any]]) -> pa.DataType:
    if column in COUNTS:
        return pa.int64()
    if column in METRICS or column == WALL_CLOCK_COLUMN or column in DIFFERENCE_COLUMNS:
        return pa.float64()
    values = [row[column] for row in rows if row.get(column) is not None]
    if values and all(isinstance(v, bool) for v in values):
        return pa.bool_()
    if values and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return pa.int64()
    if values and all(isinstance(v, numbers.Real) and not isinstance(v, bool) for v in values):
        return pa.float64()
    return pa.string()
