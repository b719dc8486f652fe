"""The house rules no off-the-shelf linter checks, run by `.ci/run` and pre-commit.

`lint-imports` (pyproject's `[tool.importlinter]`) holds the floors and forbids import
circles; ruff holds the size of a function in statements and branches (`PLR0915`,
`C901`); `deptry` holds the declared dependencies. What is left is checked here, on the
syntax tree of every module of `lagrax/`:

- **private names stay private**: no module imports another module's `_name` (a
  function, class or constant). Importing a private *module* (`from .._core import
  errors`, `from . import _rk4`) is how the wings are reached and is allowed.
- **rooms stay small**: no module over `MAX_MODULE_LINES` lines.
- **functions stay readable**: no function over `MAX_FUNCTION_LINES` code lines (its
  lines less the docstring, comments and blank lines).
- **errors are lagrax's**: no `raise` of a builtin exception class (`ValueError`,
  `TypeError`, `KeyError`, `FileNotFoundError`, `ImportError`, ..., called or not): a
  user who catches `lagrax.LagraxError` catches everything lagrax raises on purpose, so
  a reachable error is the `LagraxError` subclass that names the value (each also
  derives from the builtin it refines), and a branch that cannot be reached is a closed
  `Literal` set ended by `typing.assert_never`, which the type checker holds.
  `NotImplementedError` is not an exception: abstract methods are `abc.abstractmethod`
  or `equinox.AbstractVar`, as in equinox, and the package has none. The one exception
  is Python's own protocol: `AttributeError` raised by a `__getattr__` (a module's
  lazy names), which `getattr(obj, name, default)` relies on.
- **no `hasattr`**: what an object is is decided by `isinstance` on its class (or a
  method it has by its abstract base), never by probing for an attribute (equinox's
  pattern: abstract or final, never `hasattr`). An optional attribute of another
  library's object (a field of a newer MuJoCo, diffrax's private wrapping terms) is
  read once with `getattr(obj, name, None)` and its value used.

Usage: `python tools/house_rules.py` prints each breach and exits 1 if there is any.
"""

from __future__ import annotations

import ast
import builtins
import io
import sys
import tokenize
from pathlib import Path

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80
PACKAGE = "lagrax"


def _module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(node: ast.ImportFrom, module: str, is_package: bool) -> str | None:
    """The absolute module an `ImportFrom` reads from, or None outside the package."""
    if node.level == 0:
        name = node.module or ""
        return name if name == PACKAGE or name.startswith(PACKAGE + ".") else None
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_module(name: str, root: Path) -> bool:
    path = root.joinpath(*name.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


def private_imports(path: Path, tree: ast.Module, root: Path) -> list[str]:
    module = _module_name(path, root)
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        source = _resolve(node, module, path.name == "__init__.py")
        if source is None or source == module:
            continue
        for alias in node.names:
            name = alias.name
            if name.startswith("_") and not name.startswith("__"):
                if not _is_module(f"{source}.{name}", root):
                    out.append(f"{path}:{node.lineno}: imports the private name {source}.{name}")
    return out


def _token_lines(source: str) -> set[int]:
    """The lines of `source` that hold a token of code (not blank, not only a comment)."""
    code: set[int] = set()
    skip = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT}
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in skip:
            code.update(range(tok.start[0], tok.end[0] + 1))
    return code


def _code_lines(code: set[int], node: ast.AST) -> int:
    """Lines of `node` that hold code (`code`: the module's, from `_token_lines`): not
    blank, not only a comment, not its docstring."""
    lines = set(range(node.lineno, node.end_lineno + 1))  # type: ignore[attr-defined]
    body = getattr(node, "body", [])
    if (
        body
        and isinstance(body[0], ast.Expr)
        and isinstance(body[0].value, ast.Constant)
        and isinstance(body[0].value.value, str)
    ):
        lines -= set(range(body[0].lineno, body[0].end_lineno + 1))  # type: ignore[operator]
    return len(lines & code)


def long_functions(path: Path, tree: ast.Module, source: str) -> list[str]:
    out = []
    code = _token_lines(source)  # once per module, not once per function
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            n = _code_lines(code, node)
            if n > MAX_FUNCTION_LINES:
                out.append(
                    f"{path}:{node.lineno}: {node.name} has {n} code lines "
                    f"(at most {MAX_FUNCTION_LINES})"
                )
    return out


BUILTIN_EXCEPTIONS = frozenset(
    name
    for name, value in vars(builtins).items()
    if isinstance(value, type) and issubclass(value, BaseException)
)
# (function name, exception) pairs that Python's protocols require
PROTOCOL_RAISES = frozenset({("__getattr__", "AttributeError")})


def _raised_name(node: ast.Raise) -> str | None:
    """The builtin exception class `node` raises (`raise X`, `raise X(...)`,
    `raise builtins.X(...)`), or None for anything else (a lagrax error, a re-raise)."""
    exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
    if isinstance(exc, ast.Name):
        name = exc.id
    elif (
        isinstance(exc, ast.Attribute)
        and isinstance(exc.value, ast.Name)
        and exc.value.id == "builtins"
    ):
        name = exc.attr
    else:
        return None
    return name if name in BUILTIN_EXCEPTIONS else None


def builtin_raises(path: Path, tree: ast.Module) -> list[str]:
    """Each `raise` of a builtin exception class, outside `PROTOCOL_RAISES`."""
    out = []

    def visit(node: ast.AST, function: str | None) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                visit(child, child.name)
                continue
            if isinstance(child, ast.Raise) and (name := _raised_name(child)):
                if (function, name) not in PROTOCOL_RAISES:
                    out.append(
                        f"{path}:{child.lineno}: raises the builtin {name}: raise the "
                        "LagraxError subclass that names the value (or end a closed set "
                        "of cases with typing.assert_never)"
                    )
            visit(child, function)

    visit(tree, None)
    return out


def hasattr_calls(path: Path, tree: ast.Module) -> list[str]:
    """Each call of `hasattr`."""
    return [
        f"{path}:{node.lineno}: hasattr: decide what an object is by isinstance (or read "
        "another library's optional attribute with getattr(obj, name, None))"
        for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id == "hasattr"
    ]


def main(argv: list[str]) -> int:
    root = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parents[1]
    breaches = []
    for path in sorted((root / PACKAGE).rglob("*.py")):
        source = path.read_text(encoding="utf-8")
        tree = ast.parse(source, filename=str(path))
        rel = path.relative_to(root)
        n_lines = source.count("\n")
        if n_lines > MAX_MODULE_LINES:
            breaches.append(f"{rel}: {n_lines} lines (at most {MAX_MODULE_LINES})")
        breaches += [b.replace(str(path), str(rel)) for b in private_imports(path, tree, root)]
        breaches += [b.replace(str(path), str(rel)) for b in long_functions(path, tree, source)]
        breaches += [b.replace(str(path), str(rel)) for b in builtin_raises(path, tree)]
        breaches += [b.replace(str(path), str(rel)) for b in hasattr_calls(path, tree)]
    for line in breaches:
        print(line)
    print(f"house rules: {len(breaches)} breach(es)")
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
