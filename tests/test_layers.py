"""The import rules of docs/architecture.md ("Layers"), checked on the source tree with :mod:`ast`.

Every import counts, at module level or inside a function (also under ``TYPE_CHECKING``): an import deferred into a
function still ties the modules together. Deferring a *heavy* third-party module (torch, mediapipe) for start-up
speed is fine, as is deferring a project module that obeys the rules; what the rules forbid is an import across
layers, and an import cycle between project modules however it is hidden.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("apps", "dancesynth", "stage1_pose", "stage2_video")

# (importer, imported, why): no module under the first prefix imports one under the second.
FORBIDDEN = [
    ("dancesynth.core", "stage1_pose", "dancesynth.core imports neither stage"),
    ("dancesynth.core", "stage2_video", "dancesynth.core imports neither stage"),
    ("stage1_pose", "stage2_video", "stage1_pose never imports stage2_video"),
    ("stage2_video", "stage1_pose", "stage2_video never imports stage1_pose"),
    *[(below, top, "apps (and the Python API over it) is on top: nothing below imports it")
      for below in ("dancesynth.core", "stage1_pose", "stage2_video") for top in ("apps", "dancesynth.api")],
    ("stage1_pose.music_features", "stage1_pose.models",
     "stage1_pose.music_features finds model recipes by module path"),
]
# (importer, the only project modules it may import, why).
ALLOWED_ONLY = [
    ("stage1_pose.models", ("dancesynth.core", "stage1_pose.data", "stage1_pose.music_features", "stage1_pose.beats",
                            "stage1_pose.models"),
     "stage1_pose.models never imports upward (train, generate, evaluate, registry)"),
]
# (imported, the only importers it may have, why): the command line is the top of apps.
IMPORTED_ONLY_BY = [
    ("apps.cli", (), "apps.cli is the entry point: no module imports it"),
    ("apps.commands", ("apps.cli", "apps.commands"), "command modules are found by apps.cli only"),
    ("dancesynth.api", ("dancesynth", "apps.commands"), "the Python API is called by the commands, as by users"),
]


@dataclass(frozen=True)
class Import:
    importer: str
    imported: str
    file: Path
    line: int

    def where(self) -> str:
        return f"{self.file}:{self.line}: {self.importer} imports {self.imported}"


def within(module: str, prefix: str) -> bool:
    return module == prefix or module.startswith(prefix + ".")


def project_modules(root: Path, packages: tuple[str, ...] = PACKAGES) -> dict[str, Path]:
    """Module name -> source file, for every ``.py`` file of ``packages`` under ``root``."""
    modules = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def project_imports(root: Path, packages: tuple[str, ...] = PACKAGES) -> list[Import]:
    """Every import of a project module by a project module, at any depth of the source, resolved to the module
    imported (``from a.b import c`` is ``a.b.c`` when that is a module, else ``a.b``)."""
    modules = project_modules(root, packages)

    def resolve(name: str) -> str:
        while name not in modules and "." in name:
            name = name.rpartition(".")[0]
        return name

    found = []
    for module, path in modules.items():
        package = module if path.name == "__init__.py" else module.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join([*anchor, *([base] if base else [])])
                names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                         for alias in node.names]
            else:
                continue
            for name in names:
                if name.split(".")[0] in packages and resolve(name) != module:
                    found.append(Import(module, resolve(name), path.relative_to(root), node.lineno))
    return found


def layer_violations(imports: list[Import]) -> list[str]:
    bad = []
    for i in imports:
        bad += [f"{i.where()} ({why})" for importer, imported, why in FORBIDDEN
                if within(i.importer, importer) and within(i.imported, imported)]
        bad += [f"{i.where()} ({why})" for importer, allowed, why in ALLOWED_ONLY
                if within(i.importer, importer) and not any(within(i.imported, a) for a in allowed)]
        bad += [f"{i.where()} ({why})" for imported, importers, why in IMPORTED_ONLY_BY
                if within(i.imported, imported) and not any(within(i.importer, m) for m in importers)]
    return bad


def import_cycles(imports: list[Import]) -> list[list[str]]:
    """The cycles of the module import graph (one per strongly connected component of several modules, Tarjan),
    each as the modules' names in import order, the first repeated at the end."""
    graph: dict[str, list[str]] = {}
    for i in imports:
        graph.setdefault(i.importer, []).append(i.imported)
        graph.setdefault(i.imported, [])
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    components = []

    def connect(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while not component or component[-1] != v:
                component.append(stack.pop())
            if len(component) > 1:
                components.append(set(component))

    for v in sorted(graph):
        if v not in index:
            connect(v)
    return [_cycle_in(graph, component) for component in components]


def _cycle_in(graph: dict[str, list[str]], component: set[str]) -> list[str]:
    start = min(component)
    path, seen = [start], {start}
    while True:
        nxt = min(w for w in graph[path[-1]] if w in component)
        if nxt in seen:
            return [*path[path.index(nxt):], nxt]
        path.append(nxt)
        seen.add(nxt)


def test_every_import_keeps_to_the_layers():
    imports = project_imports(ROOT)
    assert len({i.importer for i in imports}) > 80  # the whole tree was read (92 modules import the project)
    assert layer_violations(imports) == []


def test_no_import_cycle_even_through_imports_inside_functions():
    assert import_cycles(project_imports(ROOT)) == []


@pytest.fixture
def bad_tree(tmp_path):
    files = {
        "dancesynth/__init__.py": "",
        "dancesynth/core/__init__.py": "",
        "dancesynth/core/draw.py": "def f():\n    from stage1_pose import train\n",
        "stage1_pose/__init__.py": "",
        "stage1_pose/train.py": "from apps.cli import main\n",
        "stage1_pose/models/__init__.py": "",
        "stage1_pose/models/lstm.py": "from .. import train\nfrom dancesynth.core import draw\n",
        "stage2_video/__init__.py": "",
        "stage2_video/composite.py": "import numpy\n\ndef load():\n    from stage2_video.train import KIND\n",
        "stage2_video/train.py": "from stage2_video.composite import load\nKIND = 'stage2'\n",
        "apps/__init__.py": "",
        "apps/cli.py": "",
        "apps/web.py": "def run():\n    import torch\n    from apps import cli\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    return tmp_path


def test_the_checks_catch_imports_inside_functions_relative_imports_and_cycles(bad_tree):
    imports = project_imports(bad_tree)
    assert sorted(line.split(" (")[0] for line in layer_violations(imports)) == [
        "apps/web.py:3: apps.web imports apps.cli",
        "dancesynth/core/draw.py:2: dancesynth.core.draw imports stage1_pose.train",
        "stage1_pose/models/lstm.py:1: stage1_pose.models.lstm imports stage1_pose.train",
        "stage1_pose/train.py:1: stage1_pose.train imports apps.cli",  # below apps
        "stage1_pose/train.py:1: stage1_pose.train imports apps.cli",  # and the entry point
    ]
    assert import_cycles(imports) == [["stage2_video.composite", "stage2_video.train", "stage2_video.composite"]]
