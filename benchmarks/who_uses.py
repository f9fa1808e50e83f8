"""Who uses each top-level function and class of ``dua_mujoco`` (experiments aside), and the count.

    python benchmarks/who_uses.py             # the names only tests or benchmarks use
    python benchmarks/who_uses.py --all       # every name, with who uses it

A name counts as used by a file when the file's code refers to it (a name, an attribute, an
import, or a string such as ``_LAZY``'s), outside the name's own definition and its module's
``__all__``; docstrings and comments do not count. The users: the package (``dua_mujoco`` but
the experiments and ``__init__``), its public API (a name ``dua_mujoco/__init__.py`` exports),
``experiments``, ``models``, ``tests``, ``benchmarks`` and ``notebooks`` (the cells' text).
Names are matched without their module, so a common name can show users it does not have: read
a row as a place to look. The last line is the package's Python line count as issue 41 measures
it (``find dua_mujoco -name '*.py' -not -path '*/experiments/*'``: the link
``dua_mujoco/models`` is not followed).
"""

from __future__ import annotations

import argparse
import ast
import itertools
import re
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "dua_mujoco"
INIT = PKG / "__init__.py"
LIBRARY = ("package", "public API", "experiments", "models", "notebooks")


def _name_of(node: ast.AST) -> str | None:
    """The name ``node`` refers to, if it is a reference."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    if isinstance(node, ast.alias):
        return node.name.rsplit(".", 1)[-1]
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value if re.fullmatch(r"\w+", node.value) else None
    return None


def _refs(tree: ast.AST, skip: frozenset[int] = frozenset()) -> Counter[str]:
    """The names ``tree``'s code refers to, counted, but on the lines ``skip``."""
    names = (_name_of(n) for n in ast.walk(tree) if getattr(n, "lineno", -1) not in skip)
    return Counter(n for n in names if n is not None)


def _span(node: ast.stmt, start: int | None = None) -> frozenset[int]:
    return frozenset(range(start or node.lineno, (node.end_lineno or node.lineno) + 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--all", action="store_true", help="every name, not only the test-only")
    args = parser.parse_args()
    files = sorted(p for p in PKG.rglob("*.py") if "experiments" not in p.relative_to(PKG).parts)
    trees = {p: ast.parse(p.read_text()) for p in files}
    package = {p: _refs(t) for p, t in trees.items() if p != INIT}
    groups = {
        "experiments": sorted((PKG / "experiments").rglob("*.py")),
        "models": sorted((ROOT / "models").rglob("*.py")),
        "tests": sorted((ROOT / "tests").rglob("*.py")),
        "benchmarks": sorted((ROOT / "benchmarks").rglob("*.py")),
    }
    users = {g: [_refs(ast.parse(p.read_text())) for p in ps] for g, ps in groups.items()}
    notebooks = " ".join(p.read_text() for p in (ROOT / "notebooks").glob("*.ipynb"))
    api = _refs(trees[INIT])
    test_only = 0
    for path, tree in trees.items():
        listed = [
            n
            for n in tree.body
            if isinstance(n, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets)
        ]
        in_all = frozenset().union(*(_span(n) for n in listed))
        for node in tree.body:
            if not isinstance(node, ast.FunctionDef | ast.ClassDef):
                continue
            name = node.name
            start = node.lineno - len(node.decorator_list)
            where: Counter[str] = Counter()
            where["package"] = _refs(tree, _span(node, start) | in_all)[name] + sum(
                r[name] for p, r in package.items() if p != path
            )
            where["public API"] = int(path != INIT and api[name] > 0)
            for group, refs in users.items():
                where[group] = sum(r[name] for r in refs)
            where["notebooks"] = len(re.findall(rf"\b{name}\b", notebooks))
            only_tests = not any(where[g] for g in LIBRARY)
            lines = len(_span(node, start))
            test_only += lines if only_tests else 0
            if args.all or only_tests:
                used = ", ".join(f"{g} {n}" for g, n in where.items() if n) or "nobody"
                print(f"{lines:5d}  {path.relative_to(ROOT)}:{name}  ({used})")
    kinds = Counter(kind for p in files for kind in _line_kinds(p.read_text()))
    print(f"lines of the names only tests or benchmarks use: {test_only}")
    print(
        f"Python lines in dua_mujoco/ besides experiments: {kinds.total()} (docstrings "
        f"{kinds['docstring']}, blank {kinds['blank']}, comments {kinds['comment']}, "
        f"code {kinds['code']})"
    )


def _line_kinds(src: str) -> list[str]:
    """Each line's kind: a docstring's (module, class, function, or a string under an
    assignment: first line to last), blank, a comment alone, or code."""

    def is_str(x: ast.stmt) -> bool:
        return (
            isinstance(x, ast.Expr)
            and isinstance(x.value, ast.Constant)
            and isinstance(x.value.value, str)
        )

    doc: set[int] = set()
    for node in ast.walk(ast.parse(src)):
        body = getattr(node, "body", None)
        if not isinstance(body, list) or not body:
            continue
        heads = [body[0]] if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef) else []
        after = [
            b for a, b in itertools.pairwise(body) if isinstance(a, ast.Assign | ast.AnnAssign)
        ]
        for x in heads + after:
            if is_str(x):
                doc.update(range(x.lineno, (x.end_lineno or x.lineno) + 1))
    return [
        "docstring"
        if i in doc
        else "blank"
        if not s.strip()
        else "comment"
        if s.lstrip().startswith("#")
        else "code"
        for i, s in enumerate(src.splitlines(), 1)
    ]


if __name__ == "__main__":
    main()
