"""The package's shape (issue 11): modules and functions small enough to have one job each,
and the stage order (the import-linter contract in pyproject.toml) kept."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "starsense"
MAX_MODULE_LINES = 500  # ../shared/DESIGN.md: "a module past ~500 lines ... split it"
MAX_FUNCTION_LINES = 100  # ... "or a function past ~100"; docstrings excluded


def _modules() -> list[Path]:
    return sorted(SRC.rglob("*.py"))


def _function_lengths(path: Path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            length = node.end_lineno - node.lineno + 1
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                if isinstance(first.value.value, str):
                    length -= first.end_lineno - first.lineno + 1
            yield node.name, node.lineno, length


def test_no_module_over_500_lines():
    long = {
        str(p.relative_to(SRC)): n
        for p in _modules()
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert long == {}


def test_no_function_over_100_lines():
    long = [
        f"{p.relative_to(SRC)}:{line} {name} ({n} lines)"
        for p in _modules()
        for name, line, n in _function_lengths(p)
        if n > MAX_FUNCTION_LINES
    ]
    assert long == []


def test_stage_order_contract():
    """`lint-imports` keeps the layers contract (each stage imports only earlier stages)."""
    exe = Path(sys.executable).with_name("lint-imports")
    if not exe.exists():
        found = shutil.which("lint-imports")
        if found is None:
            pytest.skip("import-linter is not installed (pip install -e '.[dev]')")
        exe = Path(found)
    run = subprocess.run(
        [str(exe), "--no-cache"], cwd=SRC.parents[1], capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
