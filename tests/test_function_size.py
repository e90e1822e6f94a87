"""Sizes a reader can hold: no function in ``millimpact/`` over :data:`MAX_CODE_LINES` code lines
and no module docstring over :data:`MAX_DOCSTRING_LINES` lines, found by walking the package with
``ast``. Code lines: lines of a function's span that hold code, not blank, not comment-only and not
part of a docstring (a nested function's lines count for it and for its parent). Both checks are
shown to fail on made-up sources (a check that cannot fail would prove nothing)."""
from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "millimpact"
#: the limit for any function: a long function is split into typed records and one function a step
MAX_CODE_LINES = 120
#: the limit for a module docstring: what the module computes, its equations and their sources
MAX_DOCSTRING_LINES = 45


def _docstring_lines(tree: ast.AST) -> set[int]:
    """Line numbers taken by the docstrings of the module, its classes and functions."""
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                lines.update(range(body[0].lineno, body[0].end_lineno + 1))
    return lines


def _code_lines(source: str) -> set[int]:
    """Line numbers that hold a token of code (not a comment, not only a line break or indent)."""
    skip = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
            tokenize.ENDMARKER, tokenize.ENCODING}
    lines: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in skip:
            lines.update(range(tok.start[0], tok.end[0] + 1))
    return lines


def long_functions(source: str, limit: int = MAX_CODE_LINES) -> list[tuple[str, int, int]]:
    """(qualified name, first line, code lines) of each function of ``source`` over ``limit``."""
    tree = ast.parse(source)
    code = _code_lines(source) - _docstring_lines(tree)
    found = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = prefix + child.name
                first = min([child.lineno] + [d.lineno for d in child.decorator_list])
                n = len([k for k in code if first <= k <= child.end_lineno])
                if n > limit:
                    found.append((name, child.lineno, n))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)
    visit(tree, "")
    return found


def module_docstring_lines(source: str) -> int:
    """Lines of the module docstring, its quotes included (0 without one)."""
    tree = ast.parse(source)
    body = tree.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        return body[0].end_lineno - body[0].lineno + 1
    return 0


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path.relative_to(PACKAGE.parent).as_posix(), path.read_text()


def test_no_function_is_longer_than_the_limit():
    offenders = [f"{rel}:{line}: {name} has {n} code lines" for rel, src in _modules()
                 for name, line, n in long_functions(src)]
    assert not offenders, (f"functions over {MAX_CODE_LINES} code lines (not blank, comment or docstring); "
                           "split each into typed records and one function a step:\n  " + "\n  ".join(offenders))


def test_no_module_docstring_is_longer_than_the_limit():
    offenders = [f"{rel}: module docstring of {n} lines" for rel, src in _modules()
                 if (n := module_docstring_lines(src)) > MAX_DOCSTRING_LINES]
    assert not offenders, (f"module docstrings over {MAX_DOCSTRING_LINES} lines; keep what the module computes, "
                           "its equations and sources, and move measurements to docs/development/:\n  "
                           + "\n  ".join(offenders))


def test_the_checks_can_fail():
    """A made-up function of limit + 1 code lines (beside comments, blanks and a docstring, which do
    not count) is found, one of exactly the limit is not, and a long module docstring is counted."""
    def function(n_code: int) -> str:
        body = "".join(f"    x{k} = {k}\n    # a comment\n\n" for k in range(n_code - 2))   # + def, return
        return f'def f():\n    """doc\n\n    more doc"""\n{body}    return 0\n'

    assert long_functions(function(MAX_CODE_LINES + 1)) == [("f", 1, MAX_CODE_LINES + 1)]
    assert long_functions(function(MAX_CODE_LINES)) == []
    nested = "class A:\n    def g(self):\n" + "".join(f"        y{k} = {k}\n" for k in range(5))
    assert long_functions(nested, limit=4) == [("A.g", 2, 6)]
    doc = '"""' + "line\n" * MAX_DOCSTRING_LINES + '"""\nx = 1\n'
    assert module_docstring_lines(doc) == MAX_DOCSTRING_LINES + 1
