"""No private name (a leading underscore) of a dice_sweep module is used outside it (issue 29).

Every module under dice_sweep/ is read as an AST; a use is ``from dice_sweep.x import _name``
(relative imports too) or ``module._name`` where ``module`` is bound to a dice_sweep module by
an import of that file (``import dice_sweep.x as m``, ``from dice_sweep.x import y`` with ``y`` a
module, or the dotted path itself). A name shared between modules is made public instead.
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
    return uses


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_private_name_crosses_a_module(path):
    module = _module_name(path)
    uses = private_uses(path.read_text(encoding="utf-8"), module, path.name == "__init__.py")
    assert not uses, f"{path.relative_to(ROOT)} uses private names of other modules: " + "; ".join(
        f"line {line}: {text}" for line, text in uses)


BAD = {
    "from_import": "from dice_sweep.measured.tracks import _split_hash\n",
    "relative_import": "from .tracks import _split_hash\n",
    "module_alias": "from dice_sweep.measured import fit as shooting\nshooting._segment_sums(1, 2)\n",
    "import_as": "import dice_sweep.measured.fit as f\nf._damped_inverse\n",
    "dotted_path": "import dice_sweep.measured.fit\ndice_sweep.measured.fit._robust_cost\n",
    "package_attribute": "from dice_sweep import measured\nmeasured.diagnose._reduce\n",
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
}


@pytest.mark.parametrize("case", sorted(GOOD))
def test_what_is_not_a_crossing(case):
    assert not private_uses(GOOD[case], "dice_sweep.measured.tracks")
