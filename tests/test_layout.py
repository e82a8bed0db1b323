"""The package's shape: modules and functions small enough to have one job each,
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


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


_NAMES = {_module_name(p): p for p in _modules()}


def _resolve(module: str, name: str | None = None) -> str | None:
    """The starsense module an import names (a submodule when ``name`` is one), else None."""
    if name is not None and f"{module}.{name}" in _NAMES:
        return f"{module}.{name}"
    path = _NAMES.get(module)
    if name is not None and path is not None and path.name == "__init__.py":
        if any(path.parent.glob(f"{name}.*")):
            return f"{module}.{name}"  # a compiled submodule (detect/_clipc.c): a leaf
    return module if path is not None else None


def _imports(path: Path):
    """Yield (line, imported module, names) for every starsense import, at any depth."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    me = _module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("starsense") and (m := _resolve(alias.name)):
                    yield node.lineno, m, ()
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*up, base] if base else up)
            if not base.startswith("starsense"):
                continue
            for alias in node.names:
                if (m := _resolve(base, alias.name)) is not None:
                    yield node.lineno, m, (() if m != base else (alias.name,))


def test_no_import_circle():
    """No chain of imports (at any depth, function-level included) leads back to its start."""
    graph = {name: set() for name in _NAMES}
    for name, path in _NAMES.items():
        for _, target, _names in _imports(path):
            if target != name and target in graph:
                graph[name].add(target)
    # Tarjan's strongly connected components: any component of 2+ modules is a circle
    index, low, stack, on, circles, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10_000))
    for v in graph:
        if v not in index:
            visit(v)
    assert circles == [], "\n".join(map(str, circles))


def _private_attributes_defined(tree: ast.Module) -> set[str]:
    """Private names a module defines itself (functions, methods, attributes set on self)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            out.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            out.add(node.attr)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            out.add(node.target.id)
        elif isinstance(node, ast.Assign):
            out.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return {n for n in out if n.startswith("_")}


def test_no_private_name_used_across_modules():
    """A module uses only the public names of another: no ``from x import _y``, no ``obj._y``
    on an object of another module's class (private modules such as ``_io`` are the package's
    own: importing the module is fine, not its private names)."""
    found = []
    for name, path in _NAMES.items():
        for line, target, names in _imports(path):
            found += [
                f"{name}:{line} imports {target}.{n}"
                for n in names
                if n.startswith("_") and not n.startswith("__") and target != name
            ]
        tree = ast.parse(path.read_text(encoding="utf-8"))
        own = _private_attributes_defined(tree)
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
                and node.attr not in own
                and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))
            ):
                found.append(f"{name}:{node.lineno} uses {ast.unparse(node)}")
    assert found == [], "\n".join(found)


#: public callables with four positional subjects: the field, the attitudes and the stars as the
#: pair (vectors, magnitudes) that ``catalog_stars`` returns and callers unpack into it
_FOUR_SUBJECTS = {"analysis/availability/field.py:FieldStars.build"}


def test_options_are_keyword_only():
    """Every public function or method of 4+ parameters takes at most 3 (its subjects)
    positionally; the options after them are keyword-only (command functions excepted: their
    signatures are the command line's)."""
    found = []
    for path in _modules():
        rel = path.relative_to(SRC)
        if rel.parts[0] == "cli" or any(
            p.startswith("_") and p != "__init__.py" for p in rel.parts
        ):
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        scopes = [(tree, "")]
        while scopes:
            node, owner = scopes.pop()
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.ClassDef) and not child.name.startswith("_"):
                    scopes.append((child, child.name + "."))
                elif isinstance(child, ast.FunctionDef) and (
                    child.name == "__init__" or not child.name.startswith("_")
                ):
                    a = child.args
                    positional = [p.arg for p in a.posonlyargs + a.args]
                    if owner and positional[:1] in (["self"], ["cls"]):
                        positional = positional[1:]
                    where = f"{rel}:{owner}{child.name}"
                    many = len(positional) + len(a.kwonlyargs) >= 4
                    if many and len(positional) > 3 and where not in _FOUR_SUBJECTS:
                        found.append(f"{where} ({len(positional)} positional)")
    assert found == []
