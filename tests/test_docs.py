"""The docs against the code: docs/dev/architecture.md is what scripts/architecture_doc.py
generates, the import graph has no cycle, every config key the docs name exists, every TOML
block of the docs is a config that loads, every link and docs/ path resolves, and the names
the developer pages use (files, tests, module attributes) exist."""

import ast
import dataclasses
import difflib
import importlib.util
import re
import typing
from pathlib import Path

import pytest

from dice_sweep import config, effects

ROOT = Path(__file__).resolve().parent.parent
DOC_FILES = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "docs" / "dev").glob("*.md")])
DEV_PAGES = [ROOT / "docs" / "dev" / "adding.md", ROOT / "docs" / "dev" / "architecture.md"]


def _architecture_script():
    spec = importlib.util.spec_from_file_location("architecture_doc", ROOT / "scripts" / "architecture_doc.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _where(path: Path, line: int) -> str:
    return f"{path.relative_to(ROOT).as_posix()}:{line}"


# --- docs/dev/architecture.md -----------------------------------------------------------------


def test_the_architecture_page_is_generated_from_the_import_graph():
    script = _architecture_script()
    page = script.expected()
    written = script.DOC.read_text()
    diff = "\n".join(list(difflib.unified_diff(written.splitlines(), page.splitlines(), "written", "generated", lineterm=""))[:40])
    assert written == page, f"docs/dev/architecture.md is out of date: run python scripts/architecture_doc.py --write\n{diff}"


def test_the_import_graph_has_no_cycle_and_no_import_up_a_floor():
    script = _architecture_script()
    graph = script.build_graph(script.read_modules())
    assert (graph.module_cycles, graph.unit_cycles, graph.upward()) == ([], [], []), script.cycles_section(graph)


def test_the_architecture_script_finds_a_cycle_and_an_import_by_name(tmp_path):
    """The check can fail: a package whose units import each other is flagged."""
    package = tmp_path / "dice_sweep"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text('"""Root."""\n')
    (package / "low.py").write_text('"""Low. More."""\nimport numpy\n')
    (package / "high.py").write_text('"""High."""\nfrom dice_sweep import low\nfrom dice_sweep.sub import inner\n')
    (package / "sub" / "__init__.py").write_text("")
    (package / "sub" / "inner.py").write_text(
        '"""Inner."""\nimport importlib\n\ndef f():\n    from dice_sweep.high import g\n    importlib.import_module(f"dice_sweep.sub.{g}")\n')
    script = _architecture_script()
    modules = script.read_modules(package)
    assert modules["dice_sweep.low"].role == "Low." and modules["dice_sweep.low"].libraries == {"numpy"}
    assert modules["dice_sweep.sub.inner"].by_name == ["dice_sweep.sub.*"]
    graph = script.build_graph(modules)
    assert graph.module_cycles == [["dice_sweep.high", "dice_sweep.sub.inner"]]
    assert graph.unit_cycles == [["high", "sub/"]]
    assert ("dice_sweep.high", "dice_sweep.sub.inner") in graph.upward()
    assert "units importing each other" in script.cycles_section(graph)


def test_every_module_has_a_test_module_at_its_mirrored_path():
    """tests/ mirrors dice_sweep/: dice_sweep/<sub>/<module>.py is tested in
    tests/<sub>/test_<module>.py (the rule of scripts/architecture_doc.py, whose page lists both
    sides); a new module without one fails here."""
    script = _architecture_script()
    have, missing, _ = script.mirrored_tests(script.read_modules())
    assert have and not missing, "modules without a test module at the mirrored path: " + ", ".join(
        f"{name} (tests/{script.mirrored_test(name).relative_to(script.ROOT / 'tests').as_posix()})" for name in missing)


def test_the_mirror_check_finds_a_module_without_its_test(tmp_path):
    """The check can fail: in a tree with dice_sweep/a.py and dice_sweep/sub/b.py, only a's test
    and a test of nothing, b is missing and the other test is reported."""
    for path, text in {"dice_sweep/__init__.py": "", "dice_sweep/__main__.py": "", "dice_sweep/a.py": '"""A."""\n',
                       "dice_sweep/sub/__init__.py": "", "dice_sweep/sub/b.py": '"""B."""\n',
                       "tests/test_a.py": "", "tests/sub/test_c.py": ""}.items():
        (tmp_path / path).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / path).write_text(text)
    script = _architecture_script()
    modules = script.read_modules(tmp_path / "dice_sweep")
    assert script.mirrored_tests(modules, tmp_path) == (["dice_sweep.a"], ["dice_sweep.sub.b"], ["tests/sub/test_c.py"])


# --- config keys -------------------------------------------------------------------------------


def _config_keys() -> set:
    """Every dotted config key (and section): the config's dataclasses and the effect registry."""
    keys = set()
    hints = typing.get_type_hints(config.Config)
    for field in dataclasses.fields(config.Config):
        kind = next((k for k in typing.get_args(hints[field.name]) if k is not type(None)), hints[field.name])
        if not dataclasses.is_dataclass(kind):
            continue
        keys.add(field.name)
        for sub in dataclasses.fields(kind):
            keys.add(f"{field.name}.{sub.name}")
            sub_kind = typing.get_type_hints(kind)[sub.name]
            if dataclasses.is_dataclass(sub_kind):  # a grid axis
                keys.update(f"{field.name}.{sub.name}.{leaf.name}" for leaf in dataclasses.fields(sub_kind))
    for section, specs in effects.config_key_specs().items():
        keys.add(section)
        keys.update(f"{section}.{name}" for name in specs)
    return keys


KEYS = _config_keys()
SECTIONS = sorted(k for k in KEYS if "." not in k)
# a word after "[section]" in prose is checked when it looks like a key: any section's key, an
# effect or a parameter name, or a word with an underscore or of one or two letters ("[world] g")
KEY_LIKE = ({k.split(".")[1] for k in KEYS if "." in k} | set(effects.names())
            | {p.name for e in effects.EFFECTS for p in e.params} | {p.name for p in effects.BASE_PARAMS})
SECTION = "|".join(SECTIONS)
BRACKET = re.compile(rf"(`?)\[({SECTION})\](`?)[ \t]+`?([A-Za-z_][A-Za-z0-9_]*)")
DOTTED = re.compile(rf"(?<![\w./-])({SECTION})\.([a-z_][a-z0-9_]*)(?:\.([a-z_][a-z0-9_]*))?(?:\[\d+\])?(?![\w(])")
NOT_KEYS = {"md", "py", "toml", "h5", "json", "png", "csv", "gz", "npz", "txt"}  # effects.md, effects.py


def _mentions(path: Path):
    """(line number, dotted key, how it was written) of every config key a Markdown file names:
    ``[section] key`` (in code, or in prose when the word looks like a key), ``section.key``,
    and the first column of a ``| key |`` table under a heading that names one ``[section]``.
    TOML blocks are left to test_every_toml_block_of_the_docs_is_a_config."""
    fence = None
    heading_sections = []
    table_section = None
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if line.lstrip().startswith("```"):
            fence = None if fence is not None else line.strip()[3:].strip()
            continue
        if fence == "toml":
            continue
        if fence is None and line.startswith("#"):
            heading_sections = re.findall(rf"\[({SECTION})\]", line)
        if fence is None and re.match(r"\|\s*key\s*\|", line):
            table_section = heading_sections[0] if len(heading_sections) == 1 else None
            continue
        if table_section and line.startswith("|"):
            first = line.split("|")[1]
            name = re.search(r"`([A-Za-z_][A-Za-z0-9_]*)`", first)
            if name and not set(first.strip()) <= set("-: "):
                yield number, f"{table_section}.{name.group(1)}", f"| `{name.group(1)}` | (a [{table_section}] table)"
        elif not line.startswith("|"):
            table_section = None
        for match in BRACKET.finditer(line):
            opened, section, closed, word = match.groups()
            in_code = fence is not None or (opened and not closed)
            if closed or not (in_code or word in KEY_LIKE or "_" in word or len(word) <= 2):
                continue
            yield number, f"{section}.{word}", match.group(0)
        for match in DOTTED.finditer(line):
            section, name, leaf = match.groups()
            if name in NOT_KEYS:
                continue
            key = f"{section}.{name}" + (f".{leaf}" if leaf and section == "grid" else "")
            yield number, key, match.group(0)


def test_every_config_key_the_docs_name_exists():
    unknown = [f"{_where(path, number)}: {text} ({key} is not a config key)"
               for path in DOC_FILES for number, key, text in _mentions(path) if key not in KEYS]
    assert not unknown, "\n".join(unknown)


def test_the_key_scan_sees_every_way_of_naming_a_key(tmp_path):
    """The scan finds each form, so the test above can fail (a mutant doc of one line each)."""
    page = tmp_path / "page.md"
    page.write_text("\n".join([
        "`[effects] nonsense = 1`",
        "--set effects.nonsense2=1",
        "the declared [world] gee_whiz",
        "## Effects (`[effects]`)",
        "| key | law |",
        "|---|---|",
        "| `nonsense3` [dx] | x |",
        "",
        "prose: [initial] values, `[grid]` replaced, docs/effects.md, effects.py, effects.names()",
    ]) + "\n")
    found = [(n, key) for n, key, _ in _mentions(page)]
    assert found == [(1, "effects.nonsense"), (2, "effects.nonsense2"), (3, "world.gee_whiz"), (7, "effects.nonsense3")]
    assert all(key not in KEYS for _, key in found)


def _toml_blocks(path: Path):
    lines = path.read_text().splitlines()
    start = None
    for number, line in enumerate(lines, 1):
        if start is None and line.strip() == "```toml":
            start = number
        elif start is not None and line.strip() == "```":
            yield start, "\n".join(lines[start:number - 1])
            start = None


@pytest.mark.parametrize("path", [p for p in DOC_FILES if "```toml" in p.read_text()], ids=lambda p: p.name)
def test_every_toml_block_of_the_docs_is_a_config(path):
    blocks = list(_toml_blocks(path))
    assert len(blocks) == path.read_text().count("```toml"), "a ```toml block not closed, or not read"
    for number, text in blocks:
        cfg = config.parse_config(text, source=_where(path, number))  # a ConfigError names the key
        assert isinstance(cfg, config.Config) and cfg.source == _where(path, number)


# --- links and paths -----------------------------------------------------------------------------


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    text = heading.strip().lstrip("#").strip().lower()
    return re.sub(r"\s", "-", re.sub(r"[^\w\- ]", "", text))


def _anchors(path: Path) -> set:
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    return {_slug(line) for line in text.splitlines() if line.startswith("#")}


def test_every_link_of_the_docs_resolves():
    broken = []
    for path in DOC_FILES:
        text = re.sub(r"```.*?```", lambda m: "\n" * m.group(0).count("\n"), path.read_text(), flags=re.S)
        for number, line in enumerate(text.splitlines(), 1):
            for target in re.findall(r"\]\(([^)\s]+)\)", line):
                if re.match(r"[a-z]+:", target):
                    continue
                file_part, _, anchor = target.partition("#")
                where = (path.parent / file_part).resolve() if file_part else path
                if not where.exists():
                    broken.append(f"{_where(path, number)}: {target} (no such file)")
                elif anchor and where.suffix == ".md" and anchor not in _anchors(where):
                    broken.append(f"{_where(path, number)}: {target} (no such heading)")
    assert not broken, "\n".join(broken)


def test_every_docs_path_named_anywhere_exists():
    """docs/*.md paths named in the docs, the package, the scripts, the tests and the Makefile."""
    sources = DOC_FILES + [ROOT / "Makefile", ROOT / "pyproject.toml"]
    sources += [p for folder in ("dice_sweep", "scripts", "tests") for p in sorted((ROOT / folder).rglob("*.py"))]
    missing = []
    for path in sources:
        for number, line in enumerate(path.read_text().splitlines(), 1):
            for name in re.findall(r"(?<![\w/.-])docs/[\w./-]*\.md", line):
                if not (ROOT / name).exists():
                    missing.append(f"{_where(path, number)}: {name}")
    assert not missing, "\n".join(missing)


# --- names the developer pages use ---------------------------------------------------------------


def _defined(path: Path) -> set:
    """Top-level names of a module: functions, classes, assignments and imported names."""
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names.update(n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


def _module_path(dotted: str) -> Path | None:
    base = ROOT.joinpath("dice_sweep", *dotted.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.exists():
            return path
    return None


def _test_names() -> set:
    return {node.name for path in (ROOT / "tests").rglob("*.py")
            for node in ast.walk(ast.parse(path.read_text())) if isinstance(node, ast.FunctionDef)}


def _name_problem(span: str, test_names: set) -> str | None:
    """What is wrong with a code span of a developer page that names a file, a test or a
    module's attribute (None: it exists, or it names none of those)."""
    span = " ".join(span.split())
    if re.fullmatch(r"test_\w+", span):
        return None if span in test_names else "no such test"
    path_part, _, test = span.partition("::")
    if re.fullmatch(r"[\w./-]+\.(py|md|toml|h5)", path_part):
        candidates = [ROOT / path_part, ROOT / "dice_sweep" / path_part]
        if "/" not in path_part:
            candidates += list((ROOT / "dice_sweep").rglob(path_part))
        found = next((p for p in candidates if p.exists()), None)
        if found is None:
            return "no such file"
        if test and test not in {n.name for n in ast.walk(ast.parse(found.read_text())) if isinstance(n, ast.FunctionDef)}:
            return "no such test in that file"
        return None
    dotted = re.fullmatch(r"(?:dice_sweep\.)?([a-z_]\w*(?:\.[A-Za-z_]\w*)+)(?:\(.*\))?", span)
    if not dotted or dotted.group(1) in KEYS or re.sub(r"\[\d+\]$", "", dotted.group(1)) in KEYS:
        return None
    parts = dotted.group(1).split(".")
    for cut in range(len(parts) - 1, 0, -1):  # the longest prefix that is a module of the package
        module = _module_path(".".join(parts[:cut]))
        if module is not None:
            name = parts[cut]
            if name in _defined(module) or _module_path(".".join(parts[: cut + 1])) is not None:
                return None
            return f"{'.'.join(parts[:cut])} has no {name}"
    return None


@pytest.mark.parametrize("path", DEV_PAGES, ids=lambda p: p.name)
def test_the_names_the_developer_pages_use_exist(path):
    """A file, a test or a module attribute a developer page names in code exists: a page that
    says how to add something goes stale when a name moves, and this says where."""
    test_names = _test_names()
    text = re.sub(r"```.*?```", lambda m: "\n" * m.group(0).count("\n"), path.read_text(), flags=re.S)
    problems = []
    for match in re.finditer(r"`([^`]+)`", text):
        problem = _name_problem(match.group(1), test_names)
        if problem:
            problems.append(f"{_where(path, text.count(chr(10), 0, match.start()) + 1)}: `{match.group(1)}`: {problem}")
    assert not problems, "\n".join(problems)
