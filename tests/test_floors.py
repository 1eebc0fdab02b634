"""The engine's floors: no import runs up the order of docs/architecture.md, no circle, imports at the top.

The order is read from the ```floors block of ``docs/architecture.md`` (its one home; the README shows a copy).
Every import of every module under ``vfit_engine/`` counts, at module top or inside a function, absolute or
relative (``from . import x``). The checker is tried on small planted trees too, so it can fail.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "architecture.md"


# ---------------------------------------------------------------------- the checker
def read_floors(text):
    """The floors of a ```floors block, lowest first: a list of lists of names (``"kernels/"``, ``"units"``).

    A line starting with a non-space opens a floor: its names, comma-separated, up to the first run of two
    or more spaces (the description follows); lines starting with spaces continue the description.
    """
    block = re.search(r"^```floors\n(.*?)^```", text, re.S | re.M)
    if block is None:
        raise AssertionError("no ```floors block")
    floors = []
    for line in block.group(1).splitlines():
        if line.strip() and not line[0].isspace():
            names = re.split(r"\s{2,}", line.strip(), maxsplit=1)[0]
            floors.append([n.strip() for n in names.split(",") if n.strip()])
    return floors


def modules(package_dir):
    """{dotted module name: (path, is_package)} of every ``.py`` file under ``package_dir``."""
    package_dir = Path(package_dir)
    found = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = [package_dir.name, *path.relative_to(package_dir).with_suffix("").parts]
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        found[".".join(parts)] = (path, is_package)
    return found


def imports(name, path, is_package, known):
    """(line, imported module, the statement) of every import of a module in ``known``, at any depth."""
    package = name.split(".")[0]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            # ``from a import b``: the module a.b when there is one, else a (b is a name in it)
            targets = [f"{source}.{alias.name}" if f"{source}.{alias.name}" in known else source
                       for alias in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:  # ``import a.b.c`` of a name c: the module a.b
                target = target.rpartition(".")[0]
            if target.split(".")[0] == package and target and target != name:
                found.append((node.lineno, target, ast.unparse(node)))
    return found


def floor_index(floors, package_dir):
    """{top-level name under the package: floor number}; checks that each name exists as the doc says."""
    index = {}
    for k, floor in enumerate(floors):
        for entry in floor:
            head = entry.rstrip("/")
            if entry.endswith("/"):
                assert (Path(package_dir) / head / "__init__.py").is_file(), f"floor {entry!r}: no such package"
            else:
                assert (Path(package_dir) / f"{head}.py").is_file(), f"floor {entry!r}: no such module"
            assert head not in index, f"{entry!r} is on two floors"
            index[head] = k
    return index


def check(package_dir, floors):
    """Problems of a package against its floors: modules on no floor, arrows up the order, circles.

    Returns a list of one-line messages naming the file, the line and the import.
    """
    package_dir = Path(package_dir)
    known = modules(package_dir)
    index = floor_index(floors, package_dir)
    rel = {name: path.relative_to(package_dir.parent).as_posix() for name, (path, _) in known.items()}

    def floor(name):
        parts = name.split(".")
        return -1 if len(parts) == 1 else index.get(parts[1])  # the package's own __init__: below every floor

    problems, graph = [], {}
    for name, (path, is_package) in known.items():
        if floor(name) is None:
            problems.append(f"{rel[name]}: on no floor (add {name.split('.')[1]!r} to the floors)")
            continue
        graph[name] = edges = {}
        for line, target, statement in imports(name, path, is_package, known):
            edges.setdefault(target, (line, statement))
            if floor(target) is not None and floor(target) > floor(name):
                problems.append(f"{rel[name]}:{line}: `{statement}` runs up from floor {floor(name) + 1} "
                                f"({', '.join(floors[floor(name)]) if floor(name) >= 0 else 'the package'}) "
                                f"to floor {floor(target) + 1} ({', '.join(floors[floor(target)])})")
    for cycle in cycles(graph):
        steps = [f"{rel[a]}:{graph[a][b][0]}: `{graph[a][b][1]}`" for a, b in zip(cycle, cycle[1:] + cycle[:1])]
        problems.append("import circle: " + " -> ".join(steps))
    return problems


def cycles(graph):
    """One circle (a list of modules) per strongly connected component of two or more modules (Tarjan)."""
    order, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        order[v] = low[v] = len(order)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in order:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], order[w])
        if low[v] == order[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(_circle_in(graph, component))

    for v in sorted(graph):
        if v not in order:
            visit(v)
    return found


def _circle_in(graph, component):
    """A circle through the component's first module, by a breadth-first search back to it."""
    start = min(component)
    parent, queue = {start: None}, [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph.get(v, ())):
            if w == start:
                path = [v]
                while parent[path[-1]] is not None:
                    path.append(parent[path[-1]])
                return path[::-1]
            if w in component and w not in parent:
                parent[w] = v
                queue.append(w)
    raise AssertionError("a strongly connected component without a circle")


def local_imports(package_dir):
    """Function-level imports without a ``# local: reason`` on their line: (file:line, statement)."""
    found = []
    for path in sorted(Path(package_dir).rglob("*.py")):
        lines = path.read_text(encoding="utf-8").splitlines()
        tree = ast.parse("\n".join(lines))
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, (ast.Import, ast.ImportFrom)) and "# local:" not in lines[node.lineno - 1]:
                        found.append((f"{path.relative_to(Path(package_dir).parent).as_posix()}:{node.lineno}",
                                      ast.unparse(node)))
    return sorted(set(found))


# ---------------------------------------------------------------------- the engine
def test_engine_keeps_its_floors():
    problems = check(ROOT / "vfit_engine", read_floors(DOC.read_text(encoding="utf-8")))
    assert not problems, "\n".join(problems)


def test_engine_imports_at_module_top():
    """Inside the engine imports go at the top, so a circle fails at import instead of hiding in a function."""
    found = local_imports(ROOT / "vfit_engine")
    assert not found, "imports inside functions (move them up, or say why on the line: `# local: ...`):\n" + \
        "\n".join(f"{where}: `{statement}`" for where, statement in found)


# ---------------------------------------------------------------------- the checker can fail
FLOORS_DOC = """\
```floors
base          the lowest
mid/          a package
top           a module
              (a continued description)
```
"""


def _tree(root, files):
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root / "pkg"


CLEAN = {
    "pkg/__init__.py": '"""pkg"""\n',
    "pkg/base.py": "X = 1\n",
    "pkg/mid/__init__.py": "from pkg.mid.a import f  # noqa\n",
    "pkg/mid/a.py": "from .. import base\nfrom . import b\n\n\ndef f():\n    from pkg.base import X\n    return X\n",
    "pkg/mid/b.py": "import pkg.base\n",
    "pkg/top.py": "from pkg.mid import a\nfrom .mid.b import pkg\n",
}


def test_read_floors():
    assert read_floors(FLOORS_DOC) == [["base"], ["mid/"], ["top"]]
    assert read_floors("```floors\na, b/  x\n  y\nc  z\n```\n") == [["a", "b/"], ["c"]]


def test_a_clean_tree_passes(tmp_path):
    assert check(_tree(tmp_path, CLEAN), read_floors(FLOORS_DOC)) == []


@pytest.mark.parametrize("planted, where, statement", [
    ("pkg/base.py", "pkg/base.py:2", "from pkg.top import Y"),  # at module top
    ("pkg/mid/b.py", "pkg/mid/b.py:2", "from ..top import Y"),  # relative
])
def test_an_upward_arrow_fails(tmp_path, planted, where, statement):
    files = dict(CLEAN)
    files[planted] += statement + "\n"
    ups = [p for p in check(_tree(tmp_path, files), read_floors(FLOORS_DOC)) if "runs up" in p]
    assert len(ups) == 1 and ups[0].startswith(f"{where}: `{statement}` runs up from floor"), ups


def test_an_upward_arrow_inside_a_function_fails(tmp_path):
    files = dict(CLEAN, **{"pkg/base.py": "X = 1\n\n\ndef g():\n    from pkg.mid import b\n    return b\n"})
    problems = check(_tree(tmp_path, files), read_floors(FLOORS_DOC))
    assert problems[0] == "pkg/base.py:5: `from pkg.mid import b` runs up from floor 1 (base) to floor 2 (mid/)"
    assert problems[1].startswith("import circle: pkg/base.py:5")  # b imports base: a circle as well


def test_a_circle_fails(tmp_path):
    files = dict(CLEAN, **{"pkg/mid/b.py": "import pkg.base\n\n\ndef h():\n    from .a import f\n"})
    (problem,) = check(_tree(tmp_path, files), read_floors(FLOORS_DOC))
    assert problem == ("import circle: pkg/mid/a.py:2: `from . import b` -> "
                       "pkg/mid/b.py:5: `from .a import f`")


def test_a_module_on_no_floor_fails(tmp_path):
    files = dict(CLEAN, **{"pkg/extra.py": "from pkg import base\n"})
    assert check(_tree(tmp_path, files), read_floors(FLOORS_DOC)) == [
        "pkg/extra.py: on no floor (add 'extra' to the floors)"]


def test_a_floor_naming_nothing_fails(tmp_path):
    with pytest.raises(AssertionError, match="'gone/': no such package"):
        check(_tree(tmp_path, CLEAN), [["base"], ["gone/"]])


def test_a_local_import_needs_a_reason(tmp_path):
    root = _tree(tmp_path, CLEAN)
    assert local_imports(root) == [("pkg/mid/a.py:6", "from pkg.base import X")]
    (root / "mid" / "a.py").write_text(CLEAN["pkg/mid/a.py"].replace("import X\n", "import X  # local: why\n"))
    assert local_imports(root) == []
