"""The house rules, checked on the source itself: imports run one way between the packages (no arrow back up),
no function over 80 lines or 8 parameters outside the Numba kernels, one module for rigid transforms, and the
linter (ruff) clean."""
import ast
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "psvs"

ARCHITECTURE = ROOT / "docs" / "architecture.md"


def read_layers(text: str) -> list[set[str]]:
    """The layers of docs/architecture.md's table, lowest first: each row ``| k | `a`, `b` | ... |``."""
    rows = re.findall(r"^\|\s*(\d+)\s*\|([^|]*)\|", text, re.M)
    layers = [set(re.findall(r"`([A-Za-z_]\w*)`", names)) for _, names in rows]
    assert [int(k) for k, _ in rows] == list(range(len(rows))), "layers numbered 0, 1, 2, ... in order"
    return layers


#: The packages' layers, lowest first (docs/architecture.md): a module may import only from strictly lower
#: layers (or its own package).
LAYERS = read_layers(ARCHITECTURE.read_text(encoding="utf-8"))
RANK = {name: k for k, layer in enumerate(LAYERS) for name in layer}
MAX_LINES, MAX_PARAMS = 80, 8


def _modules():
    for path in sorted(SRC.rglob("*.py")):
        yield path, ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _package(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return parts[0]


def _imported(tree) -> set[str]:
    """The psvs packages a module imports (``from psvs import x`` counts as package x)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "psvs":
            parts = node.module.split(".")
            out |= {parts[1]} if len(parts) > 1 else {a.name for a in node.names}
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[1] for a in node.names if a.name.startswith("psvs.")}
    return out


def test_the_layer_table_reads_as_written():
    """The parser is no looser than the table: a row out of order is an error, names are read per row."""
    assert read_layers("| 0 | `a`, `_b` | x |\n| 1 | `c` | y |\n") == [{"a", "_b"}, {"c"}]
    with pytest.raises(AssertionError, match="in order"):
        read_layers("| 0 | `a` | x |\n| 2 | `c` | y |\n")
    assert sum(map(len, LAYERS)) == len(RANK), "a package placed in two layers"


def test_readme_layout_names_every_package():
    """README's "Layout" lists every package of src/psvs (not the private modules), and only those."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    block = readme.split("## Layout", 1)[1].split("```", 2)[1]
    listed = set(re.findall(r"^src/psvs/(\w+)/", block, re.M))
    packages = {p.name for p in SRC.iterdir() if (p / "__init__.py").exists()}
    assert listed == packages, f"missing: {sorted(packages - listed)}, not packages: {sorted(listed - packages)}"


def test_every_package_has_a_layer():
    packages = {_package(path) for path, _ in _modules()}
    assert packages <= set(RANK), f"packages without a layer: {sorted(packages - set(RANK))}"


def test_imports_run_one_way():
    """No import from a package's own layer or above it (the one arrow that ran back up, simulate -> io, and
    dense -> match are gone); in particular no library module imports psvs.cli or psvs.web."""
    wrong = []
    for path, tree in _modules():
        pkg = _package(path)
        for target in _imported(tree) - {pkg}:
            if target in RANK and RANK[target] >= RANK[pkg]:
                wrong.append(f"{path.relative_to(ROOT)} imports psvs.{target}")
    assert not wrong, "\n".join(wrong)


def _is_kernel(node) -> bool:
    """A Numba-compiled function (its Python driver takes a record; the kernel itself takes arrays)."""
    return any("jit" in ast.unparse(d) or "vectorize" in ast.unparse(d) for d in node.decorator_list)


def _functions():
    for path, tree in _modules():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _is_kernel(node):
                yield path, node


def test_no_function_over_80_lines_or_8_parameters():
    long, wide = [], []
    for path, node in _functions():
        where = f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"
        lines = node.end_lineno - node.lineno + 1
        if lines > MAX_LINES:
            long.append(f"{where} ({lines} lines)")
        a = node.args
        names = [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs if x.arg not in ("self", "cls")]
        names += [x.arg for x in (a.vararg, a.kwarg) if x is not None]
        if len(names) > MAX_PARAMS:
            wide.append(f"{where} ({len(names)} parameters)")
    assert not long and not wide, "\n".join(long + wide)


def test_rigid_transforms_are_built_in_one_module():
    """psvs.transforms builds 4 x 4 transforms; nowhere else fills a matrix's rotation and translation blocks by
    hand (the code had ten such sites and three helpers of two names)."""
    hand = []
    for path, tree in _modules():
        if path.name == "transforms.py":
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Assign):
                text = ast.unparse(node.targets[0])
                if "[:3, 3]" in text or "[:3, :3]" in text:
                    hand.append(f"{path.relative_to(ROOT)}:{node.lineno} {text}")
    assert not hand, "\n".join(hand)


def test_the_linter_is_clean():
    """ruff (pyproject.toml's rules: pycodestyle, pyflakes' unused names, import order, at most 8 parameters)
    finds nothing in the sources, tests, benchmarks and examples."""
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    if ruff is None:
        pytest.fail("ruff is not installed (it is a test dependency: pip install -e .[test])")
    res = subprocess.run([ruff, "check", "--no-cache", "src", "tests", "bench", "examples", "dev.py"], cwd=ROOT,
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-1000:]


def _test_imports(tree) -> list[str]:
    """The modules of the test tree a file imports (``tests.x.y``), at any depth of the file."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "tests":
            out.append(node.module)
        elif isinstance(node, ast.Import):
            out += [a.name for a in node.names if a.name.split(".")[0] == "tests"]
    return out


def borrowed(path: Path, tree) -> list[str]:
    """What ``path`` imports from a test file or a conftest of the test tree (test support lives in
    tests/support/ and tests/reference_optics.py, fixtures in the conftests)."""
    return [f"{path.relative_to(ROOT)} imports {m}" for m in _test_imports(tree)
            if m.split(".")[-1].startswith("test_") or m.split(".")[-1] == "conftest"]


def test_no_test_file_borrows_from_another():
    """25 files imported ``run`` from tests/cli/test_cli.py, three the browser fixture from test_browser.py,
    and helpers came from conftests: shared test code lives in tests/support/ (a fixture many files use is
    a plugin of the root conftest)."""
    wrong = [line for path in sorted((ROOT / "tests").rglob("*.py"))
             for line in borrowed(path, ast.parse(path.read_text(encoding="utf-8")))]
    assert not wrong, "\n".join(wrong)


def test_the_borrowing_rule_sees_imports_at_any_depth():
    """The rule is no stronger than its detector: a module-level and a function-level import of a test
    file and of a conftest are each reported; support modules are not."""
    src = ("from tests.cli.test_cli import run\n"
           "def f():\n    from tests.web.conftest import serving\n    import tests.dense.test_sweep\n"
           "from tests.support.cli import run\n")
    found = borrowed(ROOT / "tests" / "x.py", ast.parse(src))
    assert [line.split(" imports ")[1] for line in found] == ["tests.cli.test_cli", "tests.web.conftest",
                                                              "tests.dense.test_sweep"]


def module_graph() -> dict[str, set[str]]:
    """Each psvs module (dotted name) -> the psvs modules it imports, at module level or inside a function
    (``from psvs.a import b`` is the module psvs.a.b when b is one, else psvs.a); imports for type checkers
    only (under ``if TYPE_CHECKING:``) never run and do not count."""
    names = {".".join(("psvs", *p.relative_to(SRC).with_suffix("").parts)).removesuffix(".__init__")
             for p in SRC.rglob("*.py")}
    graph = {}
    for path, tree in _modules():
        me = ".".join(("psvs", *path.relative_to(SRC).with_suffix("").parts)).removesuffix(".__init__")
        out = set()
        typing_only = {id(n) for block in ast.walk(tree) if isinstance(block, ast.If)
                       and ast.unparse(block.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING")
                       for stmt in block.body for n in ast.walk(stmt)}
        for node in ast.walk(tree):
            if id(node) in typing_only:
                continue
            if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "psvs":
                out |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in names else node.module
                        for a in node.names}
            elif isinstance(node, ast.Import):
                out |= {a.name for a in node.names if a.name in names}
        graph[me] = out & names - {me}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles of ``graph``: its strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
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

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycle_between_modules():
    """No two modules import each other, directly or around a loop, even through a function-level import
    (calibrate.charuco and calibrate.detect did, as did live.camera and live.source)."""
    found = cycles(module_graph())
    assert not found, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_the_cycle_finder_finds_cycles():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def undocumented() -> list[str]:
    """The library's public functions, classes and public classes' methods without a docstring (psvs.cli's
    command modules, Numba kernels and properties aside)."""
    out = []
    for path, tree in _modules():
        if _package(path) == "cli":
            continue
        for node in tree.body:
            methods = [n for n in node.body if isinstance(n, ast.FunctionDef)] \
                if isinstance(node, ast.ClassDef) and not node.name.startswith("_") else []
            for n in [node, *methods]:
                if not isinstance(n, (ast.FunctionDef, ast.ClassDef)) or n.name.startswith("_"):
                    continue
                if any(w in ast.unparse(d) for d in n.decorator_list for w in ("jit", "vectorize", "property")):
                    continue
                if ast.get_docstring(n) is None:
                    out.append(f"{path.relative_to(ROOT)}:{n.lineno} {n.name}")
    return out


def test_every_public_function_says_what_it_does():
    """111 public functions had no docstring (robot 26, calibrate 16, live 16); now none may."""
    missing = undocumented()
    assert not missing, "\n".join(missing)
