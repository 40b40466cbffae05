"""The shape of the package (docs/architecture.md): layers, no import cycles, small modules."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import grimp
import numpy as np
import pytest
from importlinter.cli import lint_imports
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "surfsplat"
#: The largest module allowed, in lines.
MAX_MODULE_LINES = 800


def import_cycles(graph) -> list[list[str]]:
    """Strongly connected groups of more than one module in the import graph (every import,
    top-level or inside a function)."""
    modules = sorted(graph.modules)
    index = {m: i for i, m in enumerate(modules)}
    edges = [(index[a], index[b]) for a in modules for b in graph.find_modules_directly_imported_by(a)
             if b in index and b != a]
    rows, cols = np.array(edges).T if edges else (np.array([], int), np.array([], int))
    matrix = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(modules), len(modules)))
    _, labels = connected_components(matrix, directed=True, connection="strong")
    groups: dict[int, list[str]] = {}
    for module, label in zip(modules, labels):
        groups.setdefault(label, []).append(module)
    return [g for g in groups.values() if len(g) > 1]


def test_layering_contracts_hold(monkeypatch):
    # the contracts are in pyproject.toml ([tool.importlinter]); `lint-imports` checks the same
    monkeypatch.chdir(ROOT)
    assert lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True, no_logo=True) == 0


def test_no_import_cycles_between_modules():
    graph = grimp.build_graph("surfsplat", include_external_packages=False)
    # a package's __init__ re-exporting its own modules is not a cycle of the design
    for package in [m for m in graph.modules if (PACKAGE / Path(*m.split(".")[1:]) / "__init__.py").exists()]:
        for child in graph.find_children(package):
            if graph.direct_import_exists(importer=package, imported=child):
                graph.remove_import(importer=package, imported=child)
    assert import_cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle():
    graph = grimp.ImportGraph()
    for name in ("a", "b", "c"):
        graph.add_module(name)
    graph.add_import(importer="a", imported="b")
    graph.add_import(importer="b", imported="c")
    assert import_cycles(graph) == []
    graph.add_import(importer="c", imported="a")
    assert sorted(import_cycles(graph)[0]) == ["a", "b", "c"]


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_modules_are_small(path):
    assert len(path.read_text().splitlines()) <= MAX_MODULE_LINES


#: Packages of surfsplat that load an optional dependency at import (surfsplat.diff: PyTorch): the front doors
#: (the api's ``fit``, the command line's ``fit``) import them inside the function that needs them, so
#: ``import surfsplat`` and every other command stay free of it.
LAZY_PACKAGES = {"surfsplat.diff"}


def absolute_module(path: Path, name: str) -> str:
    """The absolute module name of an import written in the module at ``path`` (relative or not)."""
    level = len(name) - len(name.lstrip("."))
    if not level:
        return name
    parts = ["surfsplat", *path.relative_to(PACKAGE).with_suffix("").parts]
    base = parts[:len(parts) - level]
    return ".".join(base + ([name[level:]] if name[level:] else []))


def test_no_imports_inside_functions_except_optional_dependencies():
    optional = {"glfw", "laspy", "lazrs", "open3d", "pandas", "pye57", "dask", "distributed", "imageio_ffmpeg",
                "matplotlib", "ipywidgets", "OpenEXR", "torch", "anywidget", "traitlets"}
    # required, but 0.7 s to import: loaded by the readers and converters of its formats only, so that
    # `import surfsplat` and the commands on PLY, LAS, ... files start without it (io/mesh.py: _trimesh)
    optional |= {"trimesh"}
    found = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for inner in ast.walk(node):
                    if isinstance(inner, ast.Import):
                        names = [a.name for a in inner.names]
                    elif isinstance(inner, ast.ImportFrom):
                        names = [("." * inner.level) + (inner.module or "")]
                    else:
                        continue
                    names = [n for n in names if n.split(".")[0] not in optional
                             and not any(f"{absolute_module(path, n)}.".startswith(f"{lazy}.")
                                         for lazy in LAZY_PACKAGES)]
                    if names:
                        found.append(f"{path.relative_to(PACKAGE)}:{inner.lineno} {', '.join(names)}")
    assert found == []


def test_import_does_not_load_trimesh():
    """``import surfsplat`` (and so every command's start) leaves trimesh unloaded (0.7 s): the readers
    of OBJ, STL, OFF, glTF and the converters import it when they run."""
    code = "import sys, surfsplat, surfsplat.cli.commands; print('trimesh' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONPATH": str(PACKAGE.parent)})
    assert out.stdout.strip() == "False"
