"""Habits the tree keeps: no source file past 800 lines, and a function longer than
``LONG_LINES`` lines says why, in a ``# long:`` comment just above it (or above its
decorators), as ruff's complexity rule asks a reason of a function with too many branches."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LONG_LINES = 80


def test_every_long_function_says_why_it_is_one() -> None:
    unexplained = []
    for folder in ("nanonav", "service", "worker", "benchmarks"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            if "migrations" in path.parts:
                continue
            lines = path.read_text(encoding="utf-8").splitlines()
            for node in ast.walk(ast.parse("\n".join(lines))):
                if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                    continue
                assert node.end_lineno is not None
                if node.end_lineno - node.lineno + 1 <= LONG_LINES:
                    continue
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                if not lines[first - 2].lstrip().startswith("# long:"):
                    unexplained.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}")
    assert unexplained == []


def test_no_source_file_is_longer_than_800_lines() -> None:
    """A file that grows past it holds several concerns: split it along them."""
    long = []
    for folder in ("nanonav", "service", "worker"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            count = len(path.read_text(encoding="utf-8").splitlines())
            if count > 800:
                long.append(f"{path.relative_to(ROOT)}: {count} lines")
    assert long == []
