"""The declared public face (docs/architecture.md): each package's ``__init__`` names what it offers
(``__all__``, each name loaded on first use), another package imports only those names, a test imports no
private name of psvs, and importing a package loads none of its modules."""
import ast
import importlib
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "psvs"
PACKAGES = sorted(p.name for p in SRC.iterdir() if (p / "__init__.py").exists())
#: psvs's own infrastructure (time and memory budgets, quiet output, threads, the compile notice, argument
#: checks): modules private by name to users, which their own tests and the library's packages import.
PRIVATE_MODULES = {p.stem for p in SRC.glob("_*.py") if not p.stem.startswith("__")}


def submodules(pkg: str) -> set[str]:
    """The names of a package's modules and subpackages."""
    return {p.stem for p in (SRC / pkg).glob("*.py") if p.stem != "__init__"} | {
        p.name for p in (SRC / pkg).iterdir() if (p / "__init__.py").exists()}


def test_every_package_declares_its_face():
    problems = []
    for pkg in PACKAGES:
        mod = importlib.import_module(f"psvs.{pkg}")
        names = getattr(mod, "__all__", None)
        if not names:
            problems.append(f"psvs.{pkg}: no __all__")
            continue
        for name in names:
            if name.startswith("_"):
                problems.append(f"psvs.{pkg}.{name}: a private name in __all__")
                continue
            value = getattr(mod, name)                  # every declared name resolves
            is_module = type(value).__name__ == "module"
            if is_module != (name in submodules(pkg)):
                problems.append(f"psvs.{pkg}.{name}: a {'module' if is_module else 'name'} that shadows or is "
                                f"shadowed by a module of the same name")
    assert problems == []


def _own_package(path: Path) -> str:
    rel = path.relative_to(SRC)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def outside_the_face(pkg: str, tree: ast.AST) -> list[str]:
    """The imports in a module of package ``pkg`` that reach into another package past its face."""
    bad = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.ImportFrom) and node.level == 0 and node.module
                and node.module.split(".")[0] == "psvs"):
            continue
        parts = node.module.split(".")
        if len(parts) == 1:                                     # from psvs import ...
            bad += [f"from psvs import {a.name}" for a in node.names
                    if a.name.startswith("_") and a.name not in PRIVATE_MODULES]
            continue
        other = parts[1]
        if other == pkg or other not in PACKAGES:
            continue
        face = importlib.import_module(f"psvs.{other}")
        declared = set(face.__all__)
        for a in node.names:
            if len(parts) > 2 and parts[2] in declared:          # a module the package declares public
                ok = not a.name.startswith("_")
            else:
                ok = a.name in declared and (len(parts) == 2 or getattr(face, a.name) is getattr(
                    importlib.import_module(node.module), a.name, None))
            if not ok:
                bad.append(f"from {node.module} import {a.name} (line {node.lineno})")
    return bad


def test_other_packages_import_only_the_face():
    bad = []
    for path in sorted(SRC.rglob("*.py")):
        bad += [f"{path.relative_to(ROOT)}: {b}" for b in outside_the_face(_own_package(path), ast.parse(
            path.read_text(encoding="utf-8")))]
    assert bad == []


def test_the_face_rule_sees_a_reach_past_it():
    planted = ast.parse("from psvs.dense.pyramid import pyramid_levels\n"
                        "def f():\n    from psvs.optics.trace import _nothing_public\n"
                        "from psvs.dense import dense_on_rig\nfrom psvs import _budget\nfrom psvs.match.x import y\n")
    assert sorted(b.split(" (")[0] for b in outside_the_face("mount", planted)) == [
        "from psvs.dense.pyramid import pyramid_levels", "from psvs.match.x import y",
        "from psvs.optics.trace import _nothing_public"]


def test_importing_a_package_loads_none_of_its_modules():
    code = ("import importlib, sys\nimport psvs\nfor pkg in sys.argv[1:]:\n"
            "    before = set(sys.modules)\n    importlib.import_module('psvs.' + pkg)\n"
            "    print(pkg, sorted(m for m in set(sys.modules) - before if m.startswith(f'psvs.{pkg}.')))\n")
    out = subprocess.run([sys.executable, "-c", code, *PACKAGES], capture_output=True, text=True, check=True,
                         cwd=ROOT).stdout.splitlines()
    assert out == [f"{pkg} []" for pkg in PACKAGES]


def private_imports(tree: ast.AST) -> list[str]:
    """A test's imports of a private name of psvs (psvs's infrastructure modules aside)."""
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module and \
                node.module.split(".")[0] == "psvs":
            path = node.module.split(".")
            bad += [f"from {node.module} import {a.name}" for a in node.names
                    if any(p.startswith("_") and p not in PRIVATE_MODULES for p in [*path, a.name])]
        elif isinstance(node, ast.Import):
            bad += [f"import {a.name}" for a in node.names if a.name.split(".")[0] == "psvs" and any(
                p.startswith("_") and p not in PRIVATE_MODULES for p in a.name.split("."))]
    return bad


def test_no_test_imports_a_private_name():
    """Nor a benchmark or an example (they break unseen when a private name is renamed: bench/ is run on
    demand, not by the suite)."""
    bad = []
    for path in sorted([*(ROOT / "tests").rglob("*.py"), *(ROOT / "bench").rglob("*.py"),
                        *(ROOT / "examples").rglob("*.py")]):
        bad += [f"{path.relative_to(ROOT)}: {b}" for b in private_imports(ast.parse(path.read_text(encoding="utf-8")))]
    assert bad == []


def test_the_private_rule_sees_a_private_import():
    planted = ast.parse("from psvs.dense.separate import _ties, separate_views\nimport psvs._budget\n"
                        "def f():\n    from psvs import _budget, _secret\n    import psvs.dense._hidden\n")
    assert private_imports(planted) == ["from psvs.dense.separate import _ties", "from psvs import _secret",
                                        "import psvs.dense._hidden"]
