"""The package's layout: stages import only the stages before them, and there are no cycles."""

from __future__ import annotations

import ast
from pathlib import Path

import precontour

PACKAGE = Path(precontour.__file__).parent
#: Pipeline order: a module may import from its own stage or an earlier one, never a later one.
STAGES = ("defaults", "errors", "files", "parallel", "kernels", "piecewise", "machine", "linuxcnc",
          "toolpath", "trajectory",
          "tables", "simulation",
          "prediction", "compensation", "planning", "options", "identification",
          "workflow", "batch",
          "reports", "system", "cnc", "cli")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


#: A result's methods that present it: the report stage's work, reached lazily.
PRESENTING = ("plot", "table")


def _plot_methods_drawing(tree: ast.AST) -> set[int]:
    """ids of the import nodes inside a result's ``plot`` or ``table`` method that import the
    report stage: figures and tables are the last stage's, and a result's ``.plot()`` or
    ``.table()`` reaches it lazily (as pandas' ``.plot`` does); the one allowed import of a
    later stage."""
    allowed = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            for item in node.body:
                if isinstance(item, ast.FunctionDef) and item.name in PRESENTING:
                    allowed.update(id(n) for n in ast.walk(item)
                                   if isinstance(n, ast.ImportFrom) and n.level
                                   and (n.module or "").startswith("reports"))
    return allowed


def _imports(path: Path) -> set[str]:
    """Absolute names of the precontour modules that ``path`` imports (anywhere in it; a
    result's ``plot`` method drawing with the report stage aside)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    tree = ast.parse(path.read_text())
    drawing = _plot_methods_drawing(tree)
    for node in ast.walk(tree):
        if id(node) in drawing:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("precontour"):
                found.add(target)
                found.update(f"{target}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("precontour"))
    return found


def _stage(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


MODULES = {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def test_every_module_belongs_to_a_stage():
    stray = sorted(m for m in MODULES if _stage(m) not in STAGES + (None, "__main__"))
    assert not stray, stray


def test_no_module_imports_a_later_stage():
    wrong = []
    for module, path in MODULES.items():
        own = _stage(module)
        if own in (None, "__main__"):
            continue
        for target in _imports(path):
            other = _stage(target)
            if other in STAGES and STAGES.index(other) > STAGES.index(own):
                wrong.append(f"{module} imports {target}")
    assert not wrong, wrong


def test_no_import_cycles():
    graph = {m: {t for t in _imports(p) if t in MODULES and t != m} for m, p in MODULES.items()}
    # A package's __init__ re-exporting its modules is not a cycle of the modules themselves.
    graph = {m: {t for t in ts if not m.startswith(t + ".")} for m, ts in graph.items()}
    state: dict[str, int] = {}

    def visit(node, trail):
        state[node] = 1
        for nxt in graph[node]:
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join(trail + [node, nxt]))
            if nxt not in state:
                visit(nxt, trail + [node])
        state[node] = 2

    for module in graph:
        if module not in state:
            visit(module, [])


def test_public_face():
    for name in ("load_machine", "load_servo", "Servo", "read_toolpath", "generate_trajectory",
                 "predict", "contour_errors", "compensate", "simulate", "Trajectory",
                 "ToolPath", "ContourErrors", "Compensation", "SimulationResult", "Machine"):
        assert name in precontour.__all__ and hasattr(precontour, name), name
    # one public function per job: the stage functions are not re-exported beside them
    for name in ("predict_tracking", "simulate_trajectory", "CompensationResult"):
        assert name not in precontour.__all__, name


def test_the_servo_goes_first_in_every_entry_point():
    import inspect

    for name in ("predict", "compensate", "simulate", "contour_errors"):
        first = next(iter(inspect.signature(getattr(precontour, name)).parameters))
        assert first == "servo", name


def test_examples_use_only_the_public_face():
    examples = sorted((Path(__file__).parents[1] / "examples").glob("[0-9][0-9]_*.py"))
    assert examples
    for path in examples:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("precontour"):
                assert node.module == "precontour", f"{path.name} imports {node.module}"
                missing = [a.name for a in node.names if a.name not in precontour.__all__]
                assert not missing, f"{path.name} imports {missing}"
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith("precontour.") for a in node.names), path.name


def test_the_command_line_holds_no_numerics():
    """The command line (precontour.cli) parses, calls one library function per command and
    prints: it imports no numerical package anywhere (not even inside a command), so any
    computing it needed would have to live in a stage, where a library caller gets it too."""
    numerical = ("numpy", "scipy", "numba", "matplotlib", "pandas", "pyarrow")
    found = []
    cli = [path for name, path in MODULES.items() if _stage(name) == "cli"]
    assert len(cli) >= 3, cli
    for node in (node for path in cli for node in ast.walk(ast.parse(path.read_text()))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        else:
            continue
        found += [name for name in names if name.split(".")[0] in numerical]
    assert not found, found


def _private_imports(path: Path) -> list[str]:
    """The precontour modules and names ``path`` imports that are private (a part of the
    dotted name, or an imported name, starting with an underscore)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("precontour") \
                or isinstance(node, ast.ImportFrom) and node.level:
            names = (node.module or "").split(".") + [a.name for a in node.names]
            found += [f"{node.module}: {name}" for name in names
                      if name.startswith("_") and name != "__version__"]
        elif isinstance(node, ast.Import):
            found += [a.name for a in node.names if a.name.startswith("precontour")
                      and any(part.startswith("_") for part in a.name.split("."))]
    return found


def test_cli_scripts_and_benchmarks_use_no_private_module_or_name():
    """The command line, the measurement scripts and the benchmarks go through what a user
    can call: nothing private (issue 40 item 7), so the docs measure the public functions."""
    root = PACKAGE.parent.parent
    files = [*sorted((PACKAGE / "cli").glob("*.py")), *sorted((root / "scripts").glob("*.py")),
             *sorted((root / "benchmarks").glob("*.py"))]
    wrong = {str(f.relative_to(root)): _private_imports(f) for f in files}
    assert not {f: names for f, names in wrong.items() if names}


def test_the_entry_points_reach_only_the_stages_entries():
    """``precontour.system`` gathers the stages' own entries: it reaches no orchestration
    (workflow, batch, cnc, cli) and no feed search (planning)."""
    reached = {_stage(t) for t in _imports(MODULES["precontour.system"])}
    assert not reached & {"workflow", "batch", "cnc", "cli", "planning", "options"}, reached


def test_the_command_line_scripts_and_benchmarks_import_no_private_module():
    """The command line, the measurement scripts and the benchmarks use what users can use:
    no precontour module or name whose name starts with an underscore (``__version__``
    aside)."""
    root = Path(__file__).resolve().parents[1]      # the source tree, installed or not
    files = [*(root / "src" / "precontour" / "cli").rglob("*.py"),
             *(root / "scripts").glob("*.py"), *(root / "benchmarks").glob("*.py")]
    assert len(files) > 10
    private = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith(
                    "precontour")):
                module = node.module or ""
                names = [a.name for a in node.names]
                if any(part.startswith("_") for part in module.split(".")) or any(
                        name.startswith("_") and not name.endswith("__") for name in names):
                    private.append(f"{path.relative_to(root)}:{node.lineno}")
    assert not private, private
