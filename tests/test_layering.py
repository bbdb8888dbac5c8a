"""The layers of DEVELOPERS.md ("Layers"), kept: the import graph read from the code, imports inside functions
included, never goes down against the documented order; torch stays out of the core, runtime and CLI, and bpy
out of every process but the simulator's worker.

The graph is derived with :mod:`ast` from every ``.py`` file of ``src/segadeform``, ``export``,
``runtimes/python`` and ``cli`` (each mapped to its installed name, ``pyproject.toml``'s ``package-dir``):
``import x``, ``from x import y``, relative imports, and ``importlib.import_module("x")`` /
``__import__("x")`` with a literal name, wherever they stand in the file.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

#: folder -> the import name it installs as
ROOTS = {
    "src/segadeform": "segadeform",
    "export": "segadeform.export",
    "runtimes/python": "segadeform.runtime",
    "cli": "segadeform.cli",
}

#: every layer, lowest first, and the layers each may import besides itself (its own and every lower one's: the
#: relation is closed transitively below).  DEVELOPERS.md draws this graph.
LAYERS = {
    "base": [],  # segadeform (the package), errors, bounds
    "io": ["base"],  # files: every reader and writer, atomic writes, locations, TOML
    "settings": ["io"],  # what a run asks for: scenes, effects, presets, simulation, cloth
    "distributed": ["io"],  # executors: local processes or Ray
    "geometry": ["settings", "distributed"],  # mesh maths: precompute, spectra, geodesics
    "body": ["geometry"],  # the body model, skinning, collisions, placement, the cloth stage
    "motion": ["body"],  # motion readers, retargeting, procedural motions
    "contracts": ["motion"],  # the model package contract (export writes it, runtimes read it)
    "preview": ["motion"],  # software rendering of meshes
    "garments": ["contracts", "preview"],  # procedural garments and garments made for another body
    "physics": ["garments"],  # the Blender simulator, out of process
    "dataset": ["physics"],  # ground-truth datasets
    "model": ["dataset"],  # torch: the SEGA network
    "train": ["model"],  # torch: training, predictors, metrics, evaluation
    "export": ["train"],  # torch -> ONNX model packages
    "runtime": ["contracts", "preview"],  # onnxruntime: packages run on scenes (never torch)
    "cli": ["runtime", "export"],  # the commands
}

#: module -> layer, by the longest matching prefix of the module's dotted name
MODULE_LAYERS = {
    "segadeform": "base",
    "segadeform.errors": "base",
    "segadeform.bounds": "base",
    "segadeform.io": "io",
    "segadeform.settings": "settings",
    "segadeform.distributed": "distributed",
    "segadeform.geometry": "geometry",
    "segadeform.body": "body",
    "segadeform.motion": "motion",
    "segadeform.contracts": "contracts",
    "segadeform.preview": "preview",
    "segadeform.garments": "garments",
    "segadeform.physics": "physics",
    "segadeform.dataset": "dataset",
    "segadeform.model": "model",
    "segadeform.train": "train",
    "segadeform.export": "export",
    "segadeform.runtime": "runtime",
    "segadeform.cli": "cli",
}

#: third-party modules only some layers may import
RESTRICTED = {
    "torch": {"model", "train", "export"},
    "onnx": {"export"},
    "onnxscript": {"export"},
    "bpy": set(),  # only the simulator's and the FBX reader's workers, in Blender's own Python (ALLOWED_MODULES)
}
#: module -> restricted imports it alone may make: the simulator's and the FBX reader's workers run inside Blender;
#: baking the body from anny (``segadeform body bake``, the ``body`` extra) runs anny, a torch library
ALLOWED_MODULES = {
    "segadeform.physics.blender_worker": {"bpy"},
    "segadeform.physics.fbx_worker": {"bpy"},
    "segadeform.body.bake_anny": {"torch"},
}
#: the modules that run inside Blender's Python, never imported by segadeform
BLENDER_SIDE = {m for m, allowed in ALLOWED_MODULES.items() if "bpy" in allowed}
#: layer -> restricted imports it may make inside functions only (the commands that train and export)
LAZY_ALLOWED = {"cli": {"torch", "onnx"}}

#: the torch-free layers (imported in a subprocess with torch blocked)
TORCH_FREE = [name for name in LAYERS if name not in RESTRICTED["torch"]]


def closure(layers: dict) -> dict:
    """layer -> every layer it may import (itself included)."""
    out = {}
    for name in layers:
        seen, todo = {name}, list(layers[name])
        while todo:
            x = todo.pop()
            if x not in seen:
                seen.add(x)
                todo.extend(layers[x])
        out[name] = seen
    return out


def modules(repo: Path = REPO) -> dict:
    """installed module name -> its file, for every module of the four roots."""
    out = {}
    for folder, pkg in ROOTS.items():
        for p in sorted((repo / folder).rglob("*.py")):
            parts = list(p.relative_to(repo / folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([pkg, *parts])] = p
    return out


def layer_of(module: str) -> str:
    parts = module.split(".")
    for k in range(len(parts), 0, -1):
        hit = MODULE_LAYERS.get(".".join(parts[:k]))
        if hit is not None:
            return hit
    raise KeyError(f"{module} is in no layer: add it to MODULE_LAYERS (and DEVELOPERS.md)")


def _imported_names(module: str, path: Path, tree: ast.AST):
    """(line, dotted name) of everything the file imports; ``from X import y`` gives ``X.y`` (a submodule or a
    name in X: :func:`import_graph` keeps what is a module)."""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            yield node.lineno, base
            for a in node.names:
                yield node.lineno, f"{base}.{a.name}"
        elif (
            isinstance(node, ast.Call)
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and isinstance(node.args[0].value, str)
        ):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
            if name in ("import_module", "__import__"):
                yield node.lineno, node.args[0].value


def _function_lines(tree: ast.AST) -> set:
    """The line numbers inside function bodies."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            out.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return out


def import_graph(repo: Path = REPO) -> tuple[set, list]:
    """``(edges, external)``: ``edges`` {(importer, imported, line)} between modules of the four roots (the
    deepest module each name reaches), ``external`` [(importer, top-level third-party name, line, inside a
    function)]."""
    mods = modules(repo)
    edges, external = set(), []
    for m, p in mods.items():
        tree = ast.parse(p.read_text(), str(p))
        lazy = _function_lines(tree)
        for line, name in _imported_names(m, p, tree):
            top = name.split(".")[0]
            if top != "segadeform":
                external.append((m, top, line, line in lazy))
                continue
            target = name
            while target not in mods and "." in target:
                target = target.rsplit(".", 1)[0]
            if target != m and target in mods:
                edges.add((m, target, line))
    return edges, external


def violations(edges, layers: dict = LAYERS) -> list[str]:
    allowed = closure(layers)
    bad = []
    for a, b, line in sorted(edges):
        la, lb = layer_of(a), layer_of(b)
        if lb not in allowed[la]:
            bad.append(f"{a} ({la}) imports {b} ({lb}) at line {line}")
    return bad


def test_every_module_has_a_layer_and_every_layer_is_documented():
    """Every module is in a layer, and DEVELOPERS.md's table has a row per layer naming where each of its
    subpackages and top-level modules is."""
    mods = modules()
    for m in mods:
        assert layer_of(m) in LAYERS, m
    assert set(MODULE_LAYERS.values()) == set(LAYERS)
    rows = {}
    for line in (REPO / "DEVELOPERS.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| `") and len(cells) == 3:
            rows[cells[0].strip("`")] = cells[1]
    assert list(rows) == list(LAYERS)
    for prefix, layer in MODULE_LAYERS.items():
        if prefix in mods and prefix not in ("segadeform", "segadeform.runtime", "segadeform.cli", "segadeform.export"):
            short = prefix.split(".", 1)[1].replace(".", "/")
            assert short.lstrip("_") in rows[layer], f"DEVELOPERS.md's row of {layer!r} does not name {short}"


def test_the_order_is_a_hierarchy():
    """No two layers may import each other, so the order is one: lowest first, every allowed layer below."""
    allowed = closure(LAYERS)
    names = list(LAYERS)
    for i, a in enumerate(names):
        assert all(names.index(b) <= i for b in allowed[a]), a


def test_no_import_goes_against_the_layers():
    edges, _ = import_graph()
    assert violations(edges) == []


def restricted(external) -> list[str]:
    """The third-party imports against :data:`RESTRICTED`."""
    return [
        f"{m} imports {top} at line {line}"
        for m, top, line, lazy in external
        if top in RESTRICTED
        and layer_of(m) not in RESTRICTED[top]
        and top not in ALLOWED_MODULES.get(m, ())
        and not (lazy and top in LAZY_ALLOWED.get(layer_of(m), ()))
    ]


def test_restricted_third_party_imports():
    """torch only in model, train and export (and inside the CLI's train and export commands); onnx in export;
    bpy in the simulator's worker alone."""
    _, external = import_graph()
    assert restricted(external) == []


def _graph_of(tmp_path, files: dict) -> tuple:
    """The graph of a made-up tree with the four roots (``files``: relative path -> source)."""
    for folder in ROOTS:
        (tmp_path / folder).mkdir(parents=True, exist_ok=True)
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    return import_graph(tmp_path)


def test_the_check_catches_back_edges_hidden_in_functions(tmp_path):
    """A function-level import of the runtime from the core, a relative one, one through importlib and torch in
    the runtime are each caught; the same imports going down are not."""
    edges, external = _graph_of(
        tmp_path,
        {
            "src/segadeform/__init__.py": "",
            "src/segadeform/io/__init__.py": "",
            "src/segadeform/io/obj.py": "def f():\n    from ..runtime import pipeline\n",
            "src/segadeform/body/__init__.py": "",
            "src/segadeform/body/model.py": "def g():\n    import importlib\n"
            "    return importlib.import_module('segadeform.garments.make')\n",
            "src/segadeform/garments/__init__.py": "",
            "src/segadeform/garments/make.py": "from segadeform.body import model\n",
            "runtimes/python/__init__.py": "",
            "runtimes/python/pipeline.py": "import numpy\n\ndef h():\n    import torch.nn\n"
            "    from segadeform.io import obj\n",
        },
    )
    bad = violations(edges)
    assert bad == [
        "segadeform.body.model (body) imports segadeform.garments.make (garments) at line 3",
        "segadeform.io.obj (io) imports segadeform.runtime (runtime) at line 2",  # (its __init__ runs)
        "segadeform.io.obj (io) imports segadeform.runtime.pipeline (runtime) at line 2",
    ]
    assert restricted(external) == ["segadeform.runtime.pipeline imports torch at line 4"]
    assert ("segadeform.garments.make", "segadeform.body.model", 1) in edges


def test_torch_free_layers_import_with_torch_blocked():
    """Every module of the torch-free layers imports (and the CLI builds its commands) with torch unavailable."""
    names = sorted(
        m for m in modules() if layer_of(m) in TORCH_FREE and m not in BLENDER_SIDE and not m.endswith("__main__")
    )
    code = (
        "import sys\n"
        "class Block:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] in ('torch', 'bpy'):\n"
        "            raise ImportError(name + ' is blocked in this test')\n"
        "sys.meta_path.insert(0, Block())\n"
        f"for m in {names!r}:\n"
        "    __import__(m)\n"
        "from segadeform.cli.main import cli\n"
        "cli.to_info_dict(__import__('click').Context(cli))\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('torch', 'bpy')))\n"
    )
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert p.returncode == 0, p.stderr[-3000:]
    assert p.stdout.strip() == "[]"
    assert len(names) > 80  # the list is derived from the tree, not written by hand


@pytest.mark.parametrize(
    "snippet", ["import bpy", "from bpy import data", "import importlib\nimportlib.import_module('bpy')"]
)
def test_bpy_anywhere_but_the_worker_is_caught(tmp_path, snippet):
    _, external = _graph_of(
        tmp_path,
        {
            "src/segadeform/__init__.py": "",
            "src/segadeform/physics/__init__.py": "",
            "src/segadeform/physics/blender.py": f"def run():\n    {snippet.replace(chr(10), chr(10) + '    ')}\n",
            "src/segadeform/physics/blender_worker.py": "import bpy\n",
        },
    )
    assert {b.split(" at ")[0] for b in restricted(external)} == {"segadeform.physics.blender imports bpy"}
