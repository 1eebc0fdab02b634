"""No module of the engine (or of the CLI, a user of it) reaches into another object's private state.

Walks the AST of every module of ``vfit_engine/`` and ``cli/`` and fails, naming file:line, on

* ``from X import _name`` / ``import X._name`` where ``_name`` is another module's private function, class
  or constant, or a private module of another top-level package (a package's own private modules, such as
  ``vfit_engine._jit`` or ``cli._common``, are its members' to import);
* ``expr._name`` where ``expr`` is not ``self``, ``cls`` or ``super()`` (this covers ``module._name`` too);
* ``getattr`` / ``setattr`` / ``hasattr`` / ``delattr`` of an object other than ``self`` / ``cls`` with a
  literal ``"_name"``.

Dunder names (``__init__``) are public. Objects own their state: what another module needs is given a public
name, an interface on the object (a method, a property, a scratch tuple) or moves to where the state lives.
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("vfit_engine", "cli")

#: Underscored names that are other libraries' public API, allowed anywhere: collections.namedtuple's
#: methods begin with an underscore only so that they cannot clash with field names.
PUBLIC_UNDERSCORED = {
    "_replace": "namedtuple's documented copy-with-changes",
    "_asdict": "namedtuple's documented dict view",
    "_fields": "namedtuple's documented field names",
    "_make": "namedtuple's documented constructor from an iterable",
}

#: (file, name) -> why: the only other underscored names allowed, each where it is used. Every entry must
#: still be used (a stale one fails :func:`test_every_allowed_exception_is_still_needed`).
ALLOWED = {
    ("cli/main.py", "_exit"):
        "os._exit is the os module's documented call to end a process without the interpreter's teardown",
    ("vfit_engine/worker_pool.py", "_processes"):
        "ProcessPoolExecutor has no public way to end its workers before Python 3.14 (terminate_workers, "
        "used when present); the fallback reads the executor's process table",
    ("vfit_engine/_jit.py", "_locator_classes"):
        "Numba's list of cache locators is its one hook for a locator of one's own (the stamp that keeps a kernel "
        "fresh when a helper it inlines from another module changes); NUMBA_CACHE_LOCATOR_CLASSES (numba >= 0.68) "
        "would replace a user's list",
    ("vfit_engine/kernel_compiles.py", "_cache_file"):
        "Numba has no public call to ask whether a function's cache is fresh: is_cached reads the index of a "
        "FunctionCache of its own (False when that fails)",
    ("vfit_engine/kernel_compiles.py", "_load_index"):
        "the same read of Numba's cache index (is_cached)",
}


def _is_own(node):
    """``self``, ``cls`` or ``super()``: an object's own state."""
    if isinstance(node, ast.Name):
        return node.id in ("self", "cls")
    return isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "super"


def _private(name):
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _absolute(module, level, importer):
    """The dotted module ``from {'.' * level}{module} import ...`` names inside module ``importer``."""
    if not level:
        return module or ""
    base = importer.split(".")[:-level]
    return ".".join(base + ([module] if module else []))


def private_access(source, path, modules, allowed=None):
    """Violations in ``source`` (the text of module file ``path``, relative to the repository, as a POSIX
    string): a list of ``(path:line: message, (path, name))``.

    ``modules`` is the set of dotted module names that exist (a private module imported from inside its own
    top-level package is allowed); ``allowed`` the (path, name) pairs to let pass (default :data:`ALLOWED`).
    """
    allowed = ALLOWED if allowed is None else allowed
    importer = path[:-len(".py")].replace("/", ".").removesuffix(".__init__")
    top = importer.split(".")[0]
    found = []

    def flag(node, name, message):
        if name in PUBLIC_UNDERSCORED or (path, name) in allowed:
            return
        found.append((f"{path}:{node.lineno}: {message}", (path, name)))

    def check_module(node, dotted):
        parts = dotted.split(".")
        if any(_private(p) for p in parts) and parts[0] != top:
            flag(node, next(p for p in parts if _private(p)), f"imports {dotted}, private to package {parts[0]}")

    for node in ast.walk(ast.parse(source, path)):
        if isinstance(node, ast.ImportFrom):
            base = _absolute(node.module, node.level, importer)
            check_module(node, base)
            for alias in node.names:
                if not _private(alias.name):
                    continue
                if f"{base}.{alias.name}" in modules:  # a module, private to its package
                    check_module(node, f"{base}.{alias.name}")
                else:
                    flag(node, alias.name, f"imports private {alias.name} from {base}")
        elif isinstance(node, ast.Import):
            for alias in node.names:
                check_module(node, alias.name)
        elif isinstance(node, ast.Attribute):
            if _private(node.attr) and not _is_own(node.value):
                flag(node, node.attr, f"reads or writes {ast.unparse(node)}, another object's private state")
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id in ("getattr", "setattr", "hasattr", "delattr") and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)
              and _private(node.args[1].value) and not _is_own(node.args[0])):
            flag(node, node.args[1].value, f"{ast.unparse(node)} reaches another object's private state")
    return found


def _module_files():
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def _module_names(files):
    names = set()
    for p in files:
        rel = p.relative_to(ROOT).with_suffix("")
        names.add(".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts))
    return names


def _all_violations(allowed=None):
    files = _module_files()
    modules = _module_names(files)
    out = []
    for p in files:
        out += private_access(p.read_text(encoding="utf-8"), p.relative_to(ROOT).as_posix(), modules, allowed)
    return out


def test_no_module_reaches_into_private_state():
    files = _module_files()
    assert len(files) > 100, "the walk found too few modules: wrong root?"
    bad = [msg for msg, _ in _all_violations()]
    assert not bad, "private state reached from outside its object:\n" + "\n".join(bad)


def test_every_allowed_exception_is_still_needed():
    used = {key for _, key in _all_violations(allowed={})}
    assert set(ALLOWED) <= used, f"stale entries in ALLOWED: {sorted(set(ALLOWED) - used)}"


PLANTED = '''\
import numpy as np
import vfit_engine._jit
from vfit_engine._jit import njit
from vfit_engine.section import MeshSections, _helper
from . import _sibling
from ._sibling import thing
from .. import _stranger
import other._hidden


class A:
    def __init__(self, s):
        self._own = s._cand
        super()._setup()
        cls = type(self)
        cls._count = getattr(s, "_visited")
        setattr(self, "_mine", 1)
        setattr(s, "_theirs", 1)

    def f(self, t):
        t = t._replace(a=1)
        self.__dunder__ = t.__class__
        return np._core, self.x._y
'''


def test_checker_flags_planted_violations():
    """The checker on a synthetic module: each kind of reach is flagged on its line, the allowed forms not."""
    modules = {"vfit_engine._jit", "vfit_engine.section", "vfit_engine.body._sibling", "vfit_engine._stranger"}
    found = private_access(PLANTED, "vfit_engine/body/planted.py", modules, allowed={})
    lines = sorted(int(msg.split(":")[1]) for msg, _ in found)
    # 4: _helper; 8: other._hidden; 13: s._cand; 16: getattr(s, "_visited"); 18: setattr(s, ...);
    # 23: np._core and self.x._y. Allowed: the package's own private modules (2, 3, 5, 6, 7), self/cls/super()
    # (13, 14, 16, 17), dunders and namedtuple's _replace (21, 22).
    assert lines == [4, 8, 13, 16, 18, 23, 23]
    assert any("imports private _helper from vfit_engine.section" in msg for msg, _ in found)
    # the same reach from another package: the engine's private modules are not the CLI's
    found = private_access("from vfit_engine import _jit\nimport vfit_engine._jit\n", "cli/x.py",
                           {"vfit_engine._jit"}, allowed={})
    assert [int(msg.split(":")[1]) for msg, _ in found] == [1, 2]
    # an allowed entry lets exactly its (file, name) pass
    found = private_access("import os\nos._exit(0)\n", "cli/main.py", set(), allowed={("cli/main.py", "_exit")})
    assert found == []
    assert len(private_access("import os\nos._exit(0)\n", "cli/other.py", set(), allowed=ALLOWED)) == 1


@pytest.mark.parametrize("source", ["x = obj._private\n", "from a.b import _f\n", "hasattr(o, '_p')\n"])
def test_checker_fails_the_walk_on_a_violation(source):
    assert private_access(source, "vfit_engine/planted.py", set(), allowed={})
