"""How the package's modules import each other, read from the source (nothing is
imported): no two modules import each other, directly or through a chain, and the
library imports nothing from the command line (:mod:`mirrorgraph.cli`) over it.

Every ``import`` counts, also those inside functions (the package imports lazily
to keep ``mirrorgraph --help`` fast, and a lazy cycle is still a cycle). A
module's parent packages, which Python runs first, are not counted as imports.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "mirrorgraph"


def _modules() -> dict[str, tuple[Path, bool]]:
    """Dotted name -> (file, whether it is a package's ``__init__``)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        out[".".join(parts[:-1] if is_package else parts)] = (path, is_package)
    return out


def _imports(name: str, path: Path, is_package: bool, known) -> set[str]:
    """The modules of the package ``name`` imports (the deepest known module of each)."""
    targets = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                here = name.split(".") if is_package else name.split(".")[:-1]
                base = ".".join(here[:len(here) - node.level + 1]
                                + ([node.module] if node.module else []))
            else:
                base = node.module
            # `from . import x` imports the module x when there is one
            targets += [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base
                        for a in node.names]
    found = set()
    for target in targets:
        while target and target not in known:
            target = target.rpartition(".")[0]
        if target and target != name:
            found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    known = _modules()
    return {name: _imports(name, path, is_package, known)
            for name, (path, is_package) in known.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm,
    iterative), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, successors = work[-1]
            for nxt in successors:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(sorted(graph[nxt]))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return found


def test_the_cycle_finder_finds_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a", "e"}, "e": {"d"}, "f": set()}
    assert sorted(cycles(graph)) == [["a", "b", "c"], ["d", "e"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_the_import_graph_is_read():
    graph = import_graph()
    assert "mirrorgraph.cli.args" in graph["mirrorgraph.cli.calibrate"]
    assert "mirrorgraph.batch" in graph["mirrorgraph.cli.batch"]            # from ..batch
    assert "mirrorgraph.report.backend" in graph["mirrorgraph.report.figures"]
    assert "mirrorgraph.pipelines.mirror" in graph["mirrorgraph.cli.calibrate"]     # inside a function


def test_no_import_cycles():
    graph = import_graph()
    found = cycles(graph)
    assert not found, "modules importing each other: " + "; ".join(
        " <-> ".join(c) + " (" + ", ".join(f"{m} -> {sorted(graph[m] & set(c))}" for m in c) + ")"
        for c in found)


def test_the_library_does_not_import_the_command_line():
    def is_cli(name: str) -> bool:
        return name == "mirrorgraph.cli" or name.startswith("mirrorgraph.cli.")

    graph = import_graph()
    offenders = {name: sorted(filter(is_cli, targets)) for name, targets in graph.items()
                 if not is_cli(name) and name != "mirrorgraph.__main__"}
    offenders = {name: cli for name, cli in offenders.items() if cli}
    assert not offenders, f"library modules importing the command line: {offenders}"


def test_no_module_takes_another_modules_private_names():
    """A name with a leading underscore is its module's own: another module that needs it
    needs it public (named, documented, tested as such)."""
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module != "__future__":
                private = [a.name for a in node.names
                           if a.name.startswith("_") and not a.name.startswith("__")]
                if private and node.module != "_version":
                    offenders.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} "
                                     f"{'.' * node.level}{node.module or ''} {private}")
    assert not offenders, "private names imported across modules: " + "; ".join(offenders)


def _imported_after(statement: str, modules: tuple[str, ...]) -> list[str]:
    """Which of ``modules`` a fresh interpreter holds after running ``statement``."""
    import json
    import os
    import subprocess
    import sys

    code = (f"import sys\n{statement}\nimport json\n"
            f"print(json.dumps([m for m in {list(modules)!r} if m in sys.modules]))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(PACKAGE.parent), *filter(None, [os.environ.get("PYTHONPATH")])])}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, check=True)
    return json.loads(out.stdout)


def test_importing_the_package_imports_no_heavy_dependency():
    """``import mirrorgraph`` stays fast: SciPy's spatial module, Matplotlib, Dask and GTSAM
    (each 0.2-0.8 s to import) wait for the first name that needs them."""
    heavy = ("scipy.spatial", "matplotlib", "dask", "distributed", "gtsam")
    assert _imported_after("import mirrorgraph", heavy) == []
    # and the names that need them still resolve, importing them then
    assert _imported_after("import mirrorgraph; mirrorgraph.calibrate", ("gtsam",)) == ["gtsam"]


def test_the_command_line_parser_imports_no_solver():
    """``mirrorgraph --help``, ``export`` and ``synth`` build the whole parser: that needs
    neither GTSAM, SciPy's optimiser (which imports its spatial module), Matplotlib, Dask
    nor the video package; the commands import them when they run."""
    heavy = ("gtsam", "scipy.optimize", "scipy.spatial", "matplotlib", "dask",
             "mirrorgraph.video", "mirrorgraph.pipelines.mirror")
    assert _imported_after("from mirrorgraph.cli import build_parser; build_parser()",
                           heavy) == []


def test_a_command_imports_its_own_module_only(tmp_path):
    """``mirrorgraph --help`` lists the commands without importing their modules, and a
    ``calibrate`` of keypoints imports neither the synthetic scenes, the video package,
    the viewer, the batch runner, Matplotlib or Dask, and of SciPy only the optimiser
    (the epipole's robust fit) with the modules it needs itself."""
    from mirrorgraph.cli import main

    assert main(["synth", "--out", str(tmp_path), "--frames", "120", "--seed", "3",
                 "--formats", "mmpose", "--quiet"]) == 0
    unwanted = ("mirrorgraph.synth", "mirrorgraph.video", "mirrorgraph.viewer",
                "mirrorgraph.batch", "matplotlib", "dask")
    run = ("import contextlib, io\nfrom mirrorgraph.cli import main\n"
           "with contextlib.redirect_stdout(io.StringIO()):\n    main({!r})")
    assert _imported_after(run.format(["--help"]), unwanted + ("mirrorgraph.cli.calibrate",
                                                               "gtsam", "cv2", "scipy")) == []
    argv = ["calibrate", str(tmp_path / "keypoints_mmpose.json"), "--intrinsics",
            str(tmp_path / "camera.json"), "--subject-height", "1.75", "--quiet",
            "--out", str(tmp_path / "c.json")]
    assert _imported_after(run.format(argv), unwanted + ("gtsam", "scipy.optimize")) == [
        "gtsam", "scipy.optimize"]
    assert (tmp_path / "c.json").is_file()
