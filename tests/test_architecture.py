"""The package's structure: one-way layers, no import cycles, no private names across modules.

The layers are declared in ``pyproject.toml`` (``[tool.importlinter]``) and
checked with import-linter; the cycle and private-name checks walk the
package's syntax trees (function-level imports included).
"""
from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "tudorvision"


def _lint_imports() -> str:
    exe = Path(sys.executable).with_name("lint-imports")
    if not exe.exists():
        found = shutil.which("lint-imports")
        if found is None:
            pytest.fail("lint-imports is not installed: `pip install -e '.[dev]'` installs import-linter")
        exe = Path(found)
    return str(exe)


def _run_lint(cwd: Path, pythonpath: Path) -> subprocess.CompletedProcess:
    env = {"PYTHONPATH": str(pythonpath), "PATH": "/usr/bin:/bin", "LANG": "C.UTF-8"}
    return subprocess.run([_lint_imports(), "--no-cache"], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=300)


def test_layer_contracts_are_kept():
    proc = _run_lint(ROOT, ROOT)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "0 broken" in proc.stdout


@pytest.mark.parametrize("module, bad_import", [
    ("stereo/__init__.py", "from ..sim import arm as _arm  # deliberately wrong\n"),
    ("joint/__init__.py", "from .. import lab as _lab  # deliberately wrong\n"),
    ("io/__init__.py", "from .. import stereo as _stereo  # deliberately wrong\n"),
])
def test_a_wrong_import_breaks_the_contracts(tmp_path, module, bad_import):
    shutil.copytree(PKG, tmp_path / "tudorvision", ignore=shutil.ignore_patterns("__pycache__", "data"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    target = tmp_path / "tudorvision" / module
    target.write_text(target.read_text() + "\n" + bad_import)
    proc = _run_lint(tmp_path, tmp_path)
    assert proc.returncode != 0, proc.stdout[-2000:]
    assert "BROKEN" in proc.stdout.upper()


# ----------------------------------------------------------------------------- AST walks
def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def _resolve(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_package else module.split(".")[:-1]
    if node.level > 1:
        base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(modules: dict[str, Path]):
    """Yield ``(importer, imported module, imported name or None, node)`` for tudorvision imports."""
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        is_pkg = path.name == "__init__.py"
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                target = _resolve(node, name, is_pkg)
                if target.split(".")[0] != "tudorvision":
                    continue
                for alias in node.names:
                    yield name, target, alias.name, node
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split(".")[0] == "tudorvision":
                        yield name, alias.name, None, node


def _module_graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> modules it imports (a name that is a submodule counts as that module)."""
    graph = {m: set() for m in modules}
    for src, target, name, _ in _imports(modules):
        dst = f"{target}.{name}" if name and f"{target}.{name}" in modules else target
        if dst in modules and dst != src:
            # a package's __init__ importing its own submodules, or a submodule importing a sibling through
            # the package, is how packages re-export: count the edge to the package only for outsiders
            if src.startswith(dst + "."):
                continue
            graph[src].add(dst)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
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
                out.append(sorted(comp))

    sys.setrecursionlimit(max(10000, sys.getrecursionlimit()))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle_between_modules():
    modules = _modules()
    cycles = _cycles(_module_graph(modules))
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _defined_private_attributes(tree: ast.AST) -> set[str]:
    """Private attribute names a module defines itself (methods, class attributes, ``self._x = ...``)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and _private(node.name):
            names.add(node.name)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store) and _private(node.attr):
            names.add(node.attr)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for t in targets:
                if isinstance(t, ast.Name) and _private(t.id):
                    names.add(t.id)
    return names


def test_no_private_name_is_used_across_modules():
    modules = _modules()
    problems = []
    for src, target, name, node in _imports(modules):
        if name and _private(name) and f"{target}.{name}" not in modules:
            problems.append(f"{modules[src].relative_to(ROOT)}:{node.lineno}: imports {target}.{name}")
        mod_parts = target.split(".")
        own_pkg = src.rsplit(".", 1)[0] if modules[src].name != "__init__.py" else src
        for i, part in enumerate(mod_parts):
            # an underscore module is private to its own subpackage
            if _private(part) and ".".join(mod_parts[:i]) != own_pkg \
                    and not own_pkg.startswith(".".join(mod_parts[:i]) + "."):
                problems.append(f"{modules[src].relative_to(ROOT)}:{node.lineno}: imports the private "
                                f"module {target}")
                break
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), filename=str(path))
        own = _defined_private_attributes(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and _private(node.attr) and node.attr not in own:
                problems.append(f"{path.relative_to(ROOT)}:{node.lineno}: uses {ast.unparse(node)}")
    assert not problems, "private names used across modules:\n" + "\n".join(problems)


def test_private_name_check_catches_a_poke(tmp_path):
    tree = ast.parse("class A:\n    def f(self, other):\n        return other._secret\n")
    own = _defined_private_attributes(tree)
    pokes = [n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute) and _private(n.attr)
             and n.attr not in own]
    assert pokes == ["_secret"]


def test_modules_stay_small():
    long = {str(p.relative_to(ROOT)): n for p in PKG.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 650}
    assert not long, f"modules over 650 lines: {long}"
