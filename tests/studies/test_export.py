"""A study's table as CSV and Parquet: the same values, column types kept in Parquet."""

from __future__ import annotations

import csv
import io

import pyarrow as pa
import pyarrow.parquet as pq

from nanonav.studies.export import to_csv, to_parquet

COLUMNS = ["job_id", "seed", "robots.policy", "learning.shared_table", "mixed", "status",
           "total_steps"]  # fmt: skip
ROWS = [
    {"job_id": 1, "seed": 0, "robots.policy": "gradient", "learning.shared_table": True,
     "mixed": 1, "status": "succeeded", "total_steps": 12.5},
    {"job_id": 2, "seed": 1, "robots.policy": "random", "learning.shared_table": False,
     "mixed": "a", "status": "failed", "total_steps": None},
]  # fmt: skip


def test_parquet_keeps_types_and_nulls() -> None:
    table = pq.read_table(io.BytesIO(to_parquet(COLUMNS, ROWS)))
    assert table.column_names == COLUMNS
    assert table.schema.field("job_id").type == pa.int64()
    assert table.schema.field("learning.shared_table").type == pa.bool_()
    assert table.schema.field("total_steps").type == pa.float64()
    assert table.schema.field("mixed").type == pa.string()
    assert table.to_pylist()[1]["total_steps"] is None
    assert table.to_pylist()[0]["mixed"] == "1"


def test_csv_has_a_header_and_empty_cells_for_missing_values() -> None:
    rows = list(csv.DictReader(io.StringIO(to_csv(COLUMNS, ROWS))))
    assert rows[0]["total_steps"] == "12.5" and rows[1]["total_steps"] == ""
    assert rows[1]["learning.shared_table"] == "False"
