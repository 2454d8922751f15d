"""The code's shape, checked: one-way layers, small functions, a command line that starts light.

The layers are the contract in ``.importlinter`` (listed there, highest first, and drawn in
docs/architecture.md).  Nothing imports upward: a new upward import fails here with the chain that makes it.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "coevo"
MAX_FUNCTION_LINES = 80


def test_no_import_points_up_a_layer() -> None:
    from importlinter.cli import lint_imports

    assert lint_imports(config_filename=str(ROOT / ".importlinter")) == 0, "an import breaks a layer: see above"


def test_the_layer_contract_names_every_package() -> None:
    """A new package must be placed in a layer, or the contract would not check it."""
    text = (ROOT / ".importlinter").read_text()
    layered = {name.strip() for line in text.split("layers =", 1)[1].splitlines() for name in line.split("|")}
    packages = {f"coevo.{p.name}" for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    modules = {f"coevo.{p.stem}" for p in PACKAGE.glob("*.py")} - {"coevo.__init__", "coevo.__main__"}
    assert packages | modules <= layered, f"not in any layer: {sorted((packages | modules) - layered)}"


def _functions() -> list[tuple[int, str]]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out.append((node.end_lineno - node.lineno + 1, f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"))
    return out


def test_no_function_is_longer_than_a_screen() -> None:
    long = sorted((n, where) for n, where in _functions() if n > MAX_FUNCTION_LINES)
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"


@pytest.mark.parametrize(("argv", "absent"), [
    (["--help"], ("numpy", "pydantic", "zenoh", "matplotlib", "scipy", "pymunk", "coevo.tasks")),
    (["status", "--help"], ("matplotlib", "scipy", "pymunk", "zenoh", "coevo.tasks")),
    (["compare", "--help"], ("matplotlib", "scipy", "zenoh")),
    (["show", "--help"], ("matplotlib", "scipy", "zenoh")),
])
def test_help_loads_only_what_the_parser_needs(argv: list[str], absent: tuple[str, ...]) -> None:
    """What makes ``coevo --help`` slow is the libraries it loads (the time is measured in benchmarks/startup.py)."""
    code = ("import sys\nfrom coevo.cli import main\ntry:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
            "print(' '.join(sorted(m for m in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, check=True).stdout
    loaded = set(out.strip().splitlines()[-1].split())
    assert not [m for m in absent if m in loaded], f"coevo {' '.join(argv)} loads {[m for m in absent if m in loaded]}"


#: The generic tier: the modules that serve every kind of learner and every task.  They find tasks and kinds by name
#: (coevo.tasks, coevo.rundir.kinds: entry points), never by a literal name, and import no task's package (the
#: contract "plugins" in .importlinter, checked above).
GENERIC = ["coevo/runs", "coevo/rundir", "coevo/console.py", "coevo/dashboard", "coevo/bus", "coevo/agents",
           "coevo/broker", "coevo/replicates", "coevo/show", "coevo/ga", "coevo/policy", "coevo/plugins.py",
           "coevo/config.py"]
#: coevo's own tasks, their behaviours and its kinds of learner.
NAMES = {"cel", "coevolution", "fuel", "door", "corridor", "tracking", "docking", "executive"}
#: Where a name is declared rather than compared with: the default kind's own declaration (as CEL's is in its package).
DECLARED = {("coevo/runs/kinds.py", "coevolution")}


def test_generic_modules_name_no_learner_kind_or_task() -> None:
    """A new kind of learner or task is a package of its own and an entry point: nothing in the generic tier
    compares a setting with a kind's, a task's or a behaviour's name (docs/architecture.md, "Adding things")."""
    found = []
    for entry in GENERIC:
        for path in sorted((ROOT / entry).rglob("*.py")) if (ROOT / entry).is_dir() else [ROOT / entry]:
            where = str(path.relative_to(ROOT))
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if (isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in NAMES
                        and (where, node.value) not in DECLARED):
                    found.append(f"{where}:{node.lineno} {node.value!r}")
    assert not found, f"a kind's, a task's or a behaviour's name in a generic module: {found}"


def test_there_are_no_import_circles() -> None:
    """No two modules of coevo import each other, directly or through others, not even inside functions."""
    import grimp

    graph = grimp.build_graph("coevo", exclude_type_checking_imports=True)  # a type named for the checker is no import
    circles = sorted({tuple(sorted((a, b))) for a in graph.modules for b in graph.find_modules_directly_imported_by(a)
                      if graph.find_shortest_chain(importer=b, imported=a) is not None})
    assert not circles, f"modules that import each other (directly or through others): {circles[:10]}"


def test_the_code_cites_only_what_the_repository_holds() -> None:
    """A reader of the package has the repository, not the tracker or the workplace's notes: no issue numbers, no
    SPEC or ZENOH-NOTES of the workplace (what they said is in docs/), and every docs/ file it names exists."""
    import re

    cite = re.compile(r"\bissues? #?\d+|\bSPEC\.md|\bSPEC §|ZENOH-NOTES")
    doc = re.compile(r"\bdocs/[\w./-]+\.(?:md|png|json)")
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            where = f"{path.relative_to(ROOT)}:{n}"
            found += [f"{where} {m.group(0)!r}" for m in cite.finditer(line)]
            found += [f"{where} {m.group(0)!r} (missing)" for m in doc.finditer(line) if not (ROOT / m.group(0)).exists()]
    assert not found, f"the code cites what the repository does not hold: {found}"
