"""Sizes a newcomer can hold: no file over 800 lines and no function over 120 in rover_env/.

A 1,500-line module or a 500-line function with nested closures is where a reader gets lost
(issue 48: diagnose was one 527-line function). C sources aside; tests and benchmarks aside.
"""

from __future__ import annotations

import ast
from pathlib import Path

import rover_env

PKG = Path(rover_env.__file__).parent
MAX_FILE = 800
MAX_FUNCTION = 120


def _sources() -> list[Path]:
    return sorted(PKG.rglob("*.py"))


def test_no_file_over_800_lines() -> None:
    long = {
        str(p.relative_to(PKG.parent)): n
        for p in _sources()
        if (n := len(p.read_text().splitlines())) > MAX_FILE
    }
    assert not long, f"files over {MAX_FILE} lines: {long}"


def test_no_function_over_120_lines() -> None:
    long = {}
    for p in _sources():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > MAX_FUNCTION:
                    long[f"{p.relative_to(PKG.parent)}:{node.lineno} {node.name}"] = n
    assert not long, f"functions over {MAX_FUNCTION} lines: {long}"
