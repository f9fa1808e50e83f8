"""The mutation check's list stays aimed (benchmarks/mutants.py; docs/testing.md).

A mutant whose text no longer occurs exactly once in its file is reported *stale* by the check,
but only when someone runs it: a refactor can leave a mutant aimed at nothing while every test
passes, and the line it guarded is then guarded by nothing. These checks run in the suite and
read files only (no build, no mutation)."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def mutants() -> ModuleType:
    spec = importlib.util.spec_from_file_location("dua_mutants", ROOT / "benchmarks" / "mutants.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # a dataclass reads its module's namespace
    try:
        spec.loader.exec_module(module)
    finally:
        del sys.modules[spec.name]
    return module


def test_every_mutant_aims_at_text_that_occurs_once(mutants: ModuleType) -> None:
    """Each mutant's text occurs exactly once in its file, and its replacement differs."""
    stale = [
        f"{m.name}: {m.path} holds its text {(ROOT / m.path).read_text().count(m.old)} times"
        for m in mutants.MUTANTS
        if (ROOT / m.path).read_text().count(m.old) != 1
    ]
    assert stale == [], "aim these again at the lines they guard:\n" + "\n".join(stale)
    assert [m.name for m in mutants.MUTANTS if m.old == m.new] == []


def test_every_mutant_is_named_once_and_its_killers_exist(mutants: ModuleType) -> None:
    """Names are unique, and every test a mutant names is a file (or a function in one) of the
    suite: a renamed killer would make the mutant's run fail for the wrong reason."""
    names = [m.name for m in mutants.MUTANTS]
    assert len(names) == len(set(names))
    missing = []
    for m in mutants.MUTANTS:
        assert m.tests, m.name
        for node in m.tests:
            path, _, test = node.partition("::")
            source = ROOT / path
            if not source.is_file():
                missing.append(f"{m.name}: {path}")
                continue
            function = re.sub(r"\[.*\]$", "", test.split("::")[-1]) if test else ""
            if function and f"def {function}(" not in source.read_text():
                missing.append(f"{m.name}: {node}")
    assert missing == []


def test_docs_table_lists_every_mutant(mutants: ModuleType) -> None:
    """docs/testing.md's table has one row for each mutant, and none for a mutant that is gone."""
    doc = (ROOT / "docs" / "testing.md").read_text()
    table = doc[doc.index("| mutant | file |") :]
    listed = re.findall(r"^\| ([a-z0-9]+(?:-[a-z0-9]+)+) \|", table, re.M)
    rows, names = set(listed), {m.name for m in mutants.MUTANTS}
    assert sorted(names - rows) == []
    assert sorted(rows - names) == []
    assert len(listed) == len(rows), "a mutant has two rows"
