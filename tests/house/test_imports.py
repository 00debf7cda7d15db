"""One import name, no import circles: the package's modules as the installed
``dsim`` sees them (docs/architecture.md).

* the static import graph of every module (function-level imports included) has no
  circle;
* every module imports on its own, first, in a fresh interpreter;
* nothing in the repository imports the folders' old top-level names (``master``,
  ``fmus``, ``build_fmus``, ``serve``, and ``dsim_serve``, serve/'s name before), which
  would load a module twice under two names.  The pythonfmu scripts are the exception:
  inside an FMU, ``fmus`` is the top-level package beside them;
* tests and benchmarks share helpers only through ``tests.support``.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from tests.support.paths import ROOT

#: import name -> folder (as setup.py maps them)
FOLDERS = {"dsim": "dsim", "dsim.master": "master", "dsim.fmus": "fmus",
           "dsim.build_fmus": "build_fmus", "dsim.serve": "serve"}
#: the folders as top-level names, and serve/'s folder before it was named as it installs
OLD_NAMES = {"master", "fmus", "build_fmus", "serve", "dsim_serve"}


def fmu_script(path: Path) -> bool:
    """A pythonfmu script: the FMU's own top-level module (``fmus`` is real there)."""
    return path.name.endswith("_fmu.py") and "fmus" in path.relative_to(ROOT).parts[:1]


def package_modules() -> dict[str, Path]:
    """Every module of the package (dotted name -> file), FMU scripts aside."""
    modules = {}
    for name, folder in FOLDERS.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            if "__pycache__" in path.parts or fmu_script(path):
                continue
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            dotted = ".".join((name,) + parts)
            modules[dotted.removesuffix(".__init__")] = path
    return modules


def imports(module: str, path: Path, known: dict) -> set[str]:
    """The package modules ``module`` imports (anywhere in it, relative imports
    resolved; ``from X import name`` counts X.name when that is a module)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base)
    return {name for name in found if name in known and name != module}


def test_the_import_graph_has_no_circle():
    modules = package_modules()
    graph = {name: imports(name, path, modules) for name, path in modules.items()}
    circles, state = [], {}

    def visit(name, trail):  # depth first; a grey node met again closes a circle
        state[name] = "grey"
        for other in sorted(graph[name]):
            if state.get(other) == "grey":
                circles.append(trail[trail.index(other):] + [other])
            elif other not in state:
                visit(other, trail + [other])
        state[name] = "black"

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    assert circles == [], "\n".join(" -> ".join(c) for c in circles)
    assert len(graph) > 100  # the whole package was read


def _bound(path: Path) -> set[str] | None:
    """The names a module binds at its top level (None: any, it has a module
    ``__getattr__``)."""
    bound: set[str] = set()

    def visit(body):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                bound.add(node.name)
            elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                for target in targets:
                    bound.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                bound.update((a.asname or a.name).split(".")[0] for a in node.names)
            elif isinstance(node, (ast.If, ast.Try, ast.With)):
                visit(node.body)
                visit(getattr(node, "orelse", []))
                for handler in getattr(node, "handlers", []):
                    visit(handler.body)

    visit(ast.parse(path.read_text()).body)
    return None if "__getattr__" in bound else bound


def _dotted(path: Path) -> str:
    """A file's module name from the repository's root (tests/support/__init__.py:
    tests.support): files of one name in two folders are two importers."""
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def test_every_name_imported_from_the_package_exists():
    """``from dsim.master.x import name``: x binds name, or x.name is a module (a name
    a move left behind fails here, also inside a function no test calls)."""
    modules = package_modules()
    bound = {name: _bound(path) for name, path in modules.items()}
    missing = []
    importers = dict(modules)  # and the repository's own users of the package
    for folder in ("examples", "tests", "benchmarks"):
        importers.update({_dotted(p): p for p in sorted((ROOT / folder).rglob("*.py"))
                          if "__pycache__" not in p.parts})
    for name, path in importers.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom):
                continue
            base = node.module or ""
            if node.level:
                parts = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            if base not in modules or bound[base] is None:
                continue
            missing += [f"{name}:{node.lineno}: {base} has no {a.name}" for a in node.names
                        if a.name != "*" and a.name not in bound[base]
                        and f"{base}.{a.name}" not in modules]
    assert missing == []


#: master/'s folders, each importing only those before it (docs/architecture.md), but
#: checks/ and sweeps/, two tools side by side that know nothing of each other; the
#: modules of master/ itself: errors and scene import no folder, settings only running/'s
#: registries (to name valid choices), api the layers up to planning/; checks/, sweeps/
#: and tools/ call the api
LAYERS = ["recording", "reading", "running", "planning", "checks", "sweeps", "tools"]
SIDE_BY_SIDE = {"checks": {"sweeps"}, "sweeps": {"checks"}}
MAY_IMPORT = {"errors": set(), "scene": set(), "processes": set(), "settings": {"running"},
              "api": set(LAYERS[:LAYERS.index("planning") + 1]), "__init__": set()}


def _folder(module: str) -> str | None:
    parts = module.split(".")
    if parts[:2] != ["dsim", "master"]:
        return None
    return parts[2] if len(parts) > 2 else "__init__"


def test_each_folder_of_the_master_imports_only_the_folders_before_it():
    modules = package_modules()
    wrong = []
    for name, path in modules.items():
        folder = _folder(name)
        if folder is None:
            continue
        allowed = MAY_IMPORT.get(folder, set(LAYERS[:LAYERS.index(folder)]) if folder in
                                 LAYERS else set())
        allowed = allowed - SIDE_BY_SIDE.get(folder, set())
        if folder in ("checks", "sweeps", "tools"):
            allowed = allowed | {"api"}  # the tools are callers of the API
        for other in imports(name, path, modules):
            target = _folder(other)
            if target == "settings" and folder in BELOW_SETTINGS:
                wrong.append(f"{name} -> {other} (nothing below planning reads settings)")
                continue
            if target in (None, folder, "__init__", "errors", "scene", "settings",
                          "processes") or (
                    target in allowed):
                continue
            wrong.append(f"{name} -> {other}")
    assert wrong == []


#: the folders below planning: they take converted values, never dsim.master.settings
BELOW_SETTINGS = {"recording", "reading", "running"}
#: everything that knows Ray, reached from outside only through its package's names
RAY = "dsim.master.running.backends.ray"


def test_ray_is_reached_only_through_its_package():
    """Ray lives in one folder (docs/architecture.md): outside it, a module of the
    master imports the package ``running.backends.ray`` (the backends, the sweep's
    entry) and none of its modules."""
    modules = package_modules()
    wrong = [f"{name} -> {other}" for name, path in modules.items()
             if not (name == RAY or name.startswith(RAY + "."))
             for other in imports(name, path, modules) if other.startswith(RAY + ".")]
    assert wrong == []
    assert any(RAY in imports(n, p, modules) for n, p in modules.items())  # it is used


def _package(module: str, path: Path) -> str:
    return module if path.name == "__init__.py" else module.rpartition(".")[0]


def test_no_module_reads_another_packages_private_names():
    """``from dsim.x.y import _name`` or ``y._name`` (y a module of the package) only
    inside y's own package: a leading underscore is a package's own business, and a
    module that reads another's breaks when that package changes (the statistics once
    read the execution's private counters)."""
    modules = package_modules()
    wrong = []
    for name, path in modules.items():
        home = _package(name, path)
        tree = ast.parse(path.read_text())
        aliases = {}  # local name -> package module it is bound to
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and not node.level and node.module in modules:
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    if full in modules:
                        aliases[alias.asname or alias.name] = full
                    elif (alias.name.startswith("_") and not alias.name.startswith("__")
                          and _package(node.module, modules[node.module]) != home):
                        wrong.append(f"{name}:{node.lineno}: {node.module}.{alias.name}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.asname and alias.name in modules:
                        aliases[alias.asname] = alias.name
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id in aliases and node.attr.startswith("_")
                    and not node.attr.startswith("__")):
                other = aliases[node.value.id]
                if _package(other, modules[other]) != home:
                    wrong.append(f"{name}:{node.lineno}: {other}.{node.attr}")
    assert wrong == []


def test_fmpys_private_names_are_used_in_one_module_only():
    """fmpy's private names (``_loadFunctions``, ``_functions``) are used by
    running/fmi/library.py and nowhere else, so that a new fmpy that changes them
    breaks one module (tests/running/test_fmpy_private_names.py checks them)."""
    users = []
    for path in sorted((ROOT / "master").rglob("*.py")):
        text = path.read_text()
        if "_loadFunctions" in text or "._functions" in text:
            users.append(path.relative_to(ROOT).as_posix())
    assert users == ["master/running/fmi/library.py"]


# One fresh interpreter imports the third-party libraries once, then forks a child per
# module: each child imports its module first among dsim's, with nothing of dsim loaded.
_CHILDREN = textwrap.dedent("""
    import importlib, os, sys
    # the third-party libraries dsim's modules use, loaded once for every child (the
    # test is about the order of dsim's own imports; a library missing here is left out)
    for library in ("numpy", "scipy.linalg", "scipy.sparse", "scipy.integrate",
                    "scipy.optimize", "scipy.interpolate", "lxml.etree", "fmpy", "ray",
                    "matplotlib.pyplot", "skfem", "pandas", "fastapi", "SALib", "rich",
                    "tqdm", "yaml"):
        try:
            importlib.import_module(library)
        except ImportError:
            pass
    bad = 0
    for name in sys.argv[1:]:
        pid = os.fork()
        if pid == 0:
            try:
                importlib.import_module(name)
                loaded = sorted(m for m in sys.modules
                                if m.split(".")[0] in ("master", "fmus", "build_fmus",
                                                       "serve", "dsim_serve", "examples"))
                if loaded:
                    raise ImportError("old top-level names loaded: " + ", ".join(loaded))
            except BaseException as error:
                print(f"{name}: {type(error).__name__}: {error}", flush=True)
                os._exit(1)
            os._exit(0)
        bad += os.waitpid(pid, 0)[1] != 0
    sys.exit(1 if bad else 0)
""")


def test_every_module_imports_alone_in_a_fresh_interpreter(tmp_path):
    names = [n for n in package_modules() if not n.endswith("__main__")]
    # from an empty folder, with the repository off the path: the installed dsim
    done = subprocess.run([sys.executable, "-I", "-c", _CHILDREN, *names], cwd=tmp_path,
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    assert done.returncode == 0, done.stdout + done.stderr[-3000:]


def test_nothing_imports_the_old_top_level_names():
    offenders = []
    for folder in ("dsim", "master", "fmus", "build_fmus", "serve", "examples", "tests",
                   "benchmarks"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            if "__pycache__" in path.parts or fmu_script(path):
                continue
            for node in ast.walk(ast.parse(path.read_text())):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                         [node.module] if isinstance(node, ast.ImportFrom) and not node.level
                         else [])
                offenders += [f"{path.relative_to(ROOT)}:{node.lineno}: {n}" for n in names
                              if n and n.split(".")[0] in OLD_NAMES]
    assert offenders == []


def test_tests_and_benchmarks_share_helpers_only_through_tests_support():
    """A test module imports nothing from another test module (they would run its tests'
    module-level set-up and tie two files together): what several of them use is in
    tests/support, and benchmarks/ takes it from there too (docs/ci.md)."""
    offenders = []
    for path in sorted([*(ROOT / "tests").rglob("*.py"), *(ROOT / "benchmarks").rglob("*.py")]):
        if "__pycache__" in path.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level:
                names = ["(relative) " + "." * node.level + (node.module or "")]
                allowed = "support" in path.relative_to(ROOT).parts
            else:
                names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                         [node.module] if isinstance(node, ast.ImportFrom) else [])
                names = [n for n in names if n and n.split(".")[0] == "tests"]
                allowed = False
            offenders += [f"{path.relative_to(ROOT)}:{node.lineno}: {n}" for n in names
                          if not allowed and not n.startswith("tests.support")]
    assert offenders == []


def test_the_web_front_end_uses_the_public_api_only():
    """``dsim serve`` (serve/) is a user of dsim like any other: it imports ``dsim`` and
    its own modules, never ``dsim.master``, and each name it takes from ``dsim`` is one
    of the public names (dsim/__init__.py's table)."""
    import dsim

    wrong = []
    for path in sorted((ROOT / FOLDERS["dsim.serve"]).rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            where = f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Import):
                wrong += [f"{where}: {a.name}" for a in node.names
                          if a.name.split(".")[:2] == ["dsim", "master"]]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                module = node.module or ""
                if module.split(".")[:2] == ["dsim", "master"]:
                    wrong.append(f"{where}: {module}")
                elif module == "dsim":
                    wrong += [f"{where}: dsim.{a.name} is not public" for a in node.names
                              if a.name not in dsim.__all__]
    assert wrong == []


def test_the_fmu_scripts_import_fmus_as_the_fmu_holds_it():
    """The other side of the rule: an FMU's script imports ``fmus`` (its resources),
    never dsim, which an FMU's host need not have."""
    scripts = sorted(p for p in (ROOT / "fmus").rglob("*_fmu.py"))
    assert len(scripts) == 4
    for script in scripts:
        roots = {(n.module or "").split(".")[0] for n in ast.walk(ast.parse(script.read_text()))
                 if isinstance(n, ast.ImportFrom) and not n.level}
        assert "fmus" in roots and "dsim" not in roots, script


#: the modules of the master that may import fmpy: the FMI boundary (running/fmi/, the
#: one description reader) and the SSP reader (fmpy's SSD schema, not FMI)
FMPY_USERS = ("dsim.master.running.fmi", "dsim.master.reading.fmi_description",
              "dsim.master.reading.ssp")


def test_fmi_is_called_only_at_the_fmi_boundary():
    """Nothing outside running/fmi/ and reading/fmi_description.py imports fmpy (the
    causal kernel, once in the in-process backend, lives beside fused_step), so that
    every FMI call is made, timed and checked in one place."""
    modules = package_modules()
    wrong = []
    for name, path in modules.items():
        if name.startswith(FMPY_USERS) or not name.startswith("dsim.master"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level
                     else [])
            wrong += [f"{name}:{node.lineno}: {n}" for n in names if n.split(".")[0] == "fmpy"]
    assert wrong == []
