"""No private name (a leading underscore) of a dice_sweep module is used outside it (issue 29):
not by another module of the package, and not by a test.

Every module under dice_sweep/ and every file under tests/ is read as an AST; a use is
``from dice_sweep.x import _name`` (relative imports too), ``module._name`` where ``module`` is
bound to a dice_sweep module by an import of that file (``import dice_sweep.x as m``,
``from dice_sweep.x import y`` with ``y`` a module, or the dotted path itself), or the name as
a string to ``setattr``/``getattr``/``delattr`` (``monkeypatch.setattr(m, "_name", ...)``,
``monkeypatch.setattr("dice_sweep.x._name", ...)``). A name shared between modules is made
public instead; a test tests what the module offers, not how it is built inside.
"""

import ast
from pathlib import Path

import pytest

import dice_sweep

PACKAGE = Path(dice_sweep.__file__).resolve().parent
ROOT = PACKAGE.parent


def _modules():
    return sorted(PACKAGE.rglob("*.py"))


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(dotted):
    """Whether ``dotted`` names a module or package of dice_sweep (a file, not an attribute)."""
    if dotted.split(".")[0] != "dice_sweep":
        return False
    base = ROOT.joinpath(*dotted.split("."))
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def _private(name):
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _absolute(node, module, is_package):
    """The absolute module of an ImportFrom (relative ones resolved against ``module``)."""
    if not node.level:
        return node.module or ""
    parts = module.split(".")
    base = parts if is_package else parts[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _dotted(node):
    """``a.b.c`` of a chain of Name and Attribute nodes, else None."""
    names = []
    while isinstance(node, ast.Attribute):
        names.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return ".".join([node.id, *reversed(names)])


def private_uses(source, module, is_package=False):
    """``(line, text)`` of every use of another dice_sweep module's private name in ``source``
    (the text of module ``module``)."""
    tree = ast.parse(source)
    bound = {}  # local name -> the dice_sweep module it is bound to
    uses = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] != "dice_sweep":
                    continue
                if alias.asname:
                    bound[alias.asname] = alias.name
                else:
                    bound["dice_sweep"] = "dice_sweep"  # `import dice_sweep.x` binds the package
        elif isinstance(node, ast.ImportFrom):
            source_module = _absolute(node, module, is_package)
            if source_module.split(".")[0] != "dice_sweep":
                continue
            for alias in node.names:
                if _private(alias.name) and source_module != module:
                    uses.append((node.lineno, f"from {source_module} import {alias.name}"))
                if _is_module(f"{source_module}.{alias.name}"):
                    bound[alias.asname or alias.name] = f"{source_module}.{alias.name}"
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and _private(node.attr)):
            continue
        chain = _dotted(node.value)
        if chain is None:
            continue
        head, _, rest = chain.partition(".")
        if head not in bound:
            continue
        target = ".".join([bound[head]] + ([rest] if rest else []))
        if _is_module(target) and target != module:
            uses.append((node.lineno, f"{chain}.{node.attr}"))
    for node in ast.walk(tree):  # setattr(m, "_name"), monkeypatch.setattr("dice_sweep.m._name"), getattr, delattr
        func = node.func if isinstance(node, ast.Call) else None
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
        if name not in ("setattr", "getattr", "delattr") or not node.args:
            continue
        first, second = node.args[0], node.args[1] if len(node.args) > 1 else None
        if isinstance(first, ast.Constant) and isinstance(first.value, str) and "." in first.value:
            owner, _, attr = first.value.rpartition(".")
            if _private(attr) and _is_module(owner) and owner != module:
                uses.append((node.lineno, f"{name}({first.value!r})"))
            continue
        chain = _dotted(first)
        if chain is None or not (isinstance(second, ast.Constant) and isinstance(second.value, str) and _private(second.value)):
            continue
        head, _, rest = chain.partition(".")
        target = ".".join([bound[head]] + ([rest] if rest else [])) if head in bound else None
        if target is not None and _is_module(target) and target != module:
            uses.append((node.lineno, f"{name}({chain}, {second.value!r})"))
    return uses


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_private_name_crosses_a_module(path):
    module = _module_name(path)
    uses = private_uses(path.read_text(encoding="utf-8"), module, path.name == "__init__.py")
    assert not uses, f"{path.relative_to(ROOT)} uses private names of other modules: " + "; ".join(
        f"line {line}: {text}" for line, text in uses)


TESTS = ROOT / "tests"

# Private names tests still need, each until the package offers what they test (a change of
# dice_sweep/ that this test cannot make): file -> the uses, as private_uses words them. An
# entry no longer used fails too, so that the list only shrinks.
KNOWN = {}


def _test_files():
    return sorted(p for p in TESTS.rglob("*.py") if p.resolve() != Path(__file__).resolve())


def _uses_in_test(path):
    name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
    return {text for _, text in private_uses(path.read_text(encoding="utf-8"), name)}


@pytest.mark.parametrize("path", _test_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_test_uses_a_private_name_of_the_package(path):
    known = KNOWN.get(path.relative_to(ROOT).as_posix(), set())
    uses = _uses_in_test(path) - known
    assert not uses, f"{path.relative_to(ROOT)} uses private names of dice_sweep (test the public behaviour): " + "; ".join(sorted(uses))


def test_every_known_private_use_is_still_there():
    for relative, known in KNOWN.items():
        path = ROOT / relative
        assert path.exists(), f"{relative}: gone; drop it from KNOWN"
        gone = known - _uses_in_test(path)
        assert not gone, f"{relative} no longer uses {sorted(gone)}: drop it from KNOWN"


BAD = {
    "from_import": "from dice_sweep.measured.tracks import _split_hash\n",
    "relative_import": "from .tracks import _split_hash\n",
    "module_alias": "from dice_sweep.measured import fit as shooting\nshooting._segment_sums(1, 2)\n",
    "import_as": "import dice_sweep.measured.fit as f\nf._damped_inverse\n",
    "dotted_path": "import dice_sweep.measured.fit\ndice_sweep.measured.fit._robust_cost\n",
    "package_attribute": "from dice_sweep import measured\nmeasured.diagnose._reduce\n",
    "monkeypatch_attribute": "from dice_sweep import startup\nmonkeypatch.setattr(startup, '_notified', [])\n",
    "monkeypatch_string": "monkeypatch.setattr('dice_sweep.distributed._check_workers', f)\n",
    "getattr_string": "import dice_sweep.measured.fit as f\ngetattr(f, '_damping_floor')\n",
    "test_module": "from dice_sweep.physics.kernel import _flat_side\n",
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_each_kind_of_use_is_caught(case):
    assert private_uses(BAD[case], "dice_sweep.measured.other")


GOOD = {
    "public": "from dice_sweep.measured import fit as shooting\nshooting.segment_sums(1, 2)\n",
    "dunder": "from dice_sweep import __version__\n",
    "own_module": "from dice_sweep.measured.tracks import _split_hash\n",
    "object_attribute": "from dice_sweep.storage import SweepFile\nSweepFile.open('f')._h5\n",
    "other_library": "import os\nos._exit(1)\n",
    "a_class_not_a_module": "from dice_sweep.measured.fit import ShootingModel\nShootingModel._private\n",
    "setattr_public": "from dice_sweep import engine\nmonkeypatch.setattr(engine, 'plain', f)\n",
    "setattr_not_a_module": "setattr(cfg, '_cache', 1)\nmonkeypatch.setattr('os._exit', f)\n",
}


@pytest.mark.parametrize("case", sorted(GOOD))
def test_what_is_not_a_crossing(case):
    assert not private_uses(GOOD[case], "dice_sweep.measured.tracks")
