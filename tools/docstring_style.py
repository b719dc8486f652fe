"""Convert lagrax's docstrings from reST markup to the Markdown that mkdocstrings renders.

The documentation site (``mkdocs.yml``) renders docstrings as Markdown, as diffrax and
equinox do. This script rewrites, inside docstrings only (module, class, function and
attribute docstrings, found with ``ast``; code and error messages are never touched):

- reST roles ``:class:`x```, ``:func:``, ``:meth:``, ``:attr:``, ``:mod:``, ``:data:``,
  ``:obj:``, ``:exc:`` (with ``~`` for the short name): a cross-reference
  ``[`x`][lagrax.path.x]`` (``[`lagrax.x`][]`` when the text is the full name) when the
  name resolves to a public lagrax object that the API reference documents, else plain
  code `` `x` ``;
- reST literals (double backticks) to Markdown code (single backticks);
- ``.. math::`` directives (inline or indented blocks) to ``$$ … $$`` display blocks, one
  per paragraph of the directive;
- a blank line before a list that follows a paragraph directly (Markdown needs one).

It is idempotent: a second run changes nothing. Usage:

    python tools/docstring_style.py [--check] [PATH ...]     # default: lagrax/

``--check`` rewrites nothing and exits 1 if a file would change (for CI or a hook).
Files that other branches were editing when this was written are skipped by default
(``EXCLUDE``); pass them explicitly to convert them.
"""

from __future__ import annotations

import argparse
import ast
import difflib
import functools
import importlib
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# files left out of the conversion (none: every docstring under lagrax/ is converted)
EXCLUDE: set[str] = set()
EXCLUDE_DIRS: tuple[str, ...] = ()

# public modules, in the order relative names are looked up in
PUBLIC_MODULES = (
    "lagrax",
    "lagrax.bodies",
    "lagrax.chains",
    "lagrax.rigid_body",
    "lagrax.newton_euler",
    "lagrax.models",
    "lagrax.plot",
    "lagrax.integrators",
    "lagrax.bench",
    "lagrax.symbolic",
)

ROLE = re.compile(r":(?:py:)?(class|func|meth|attr|mod|data|obj|exc):`([^`]+)`")
LITERAL = re.compile(r"(?<!`)``([^`\n]+?)``(?!`)")
MATH = re.compile(r"^(?P<indent>[ \t]*)\.\. math::[ \t]*(?P<rest>.*)$")
LINE_LENGTH = 100  # ruff's, from pyproject.toml
LIST_ITEM = re.compile(r"^(?P<indent>[ \t]*)(?:[-*+]|\d+[.)])[ \t]+\S")


# ---------------------------------------------------------------- cross-reference targets


def _public_names(module_name: str) -> list[str]:
    module = importlib.import_module(module_name)
    names = getattr(module, "__all__", None)
    if names is None:
        names = [n for n in vars(module) if not n.startswith("_")]
    return list(names)


@functools.cache
def _public_objects() -> dict[str, object]:
    """Every documented public path (modules' public names and their classes' members)."""
    paths: dict[str, object] = {}
    for module_name in PUBLIC_MODULES:
        module = importlib.import_module(module_name)
        paths[module_name] = module
        for name in _public_names(module_name):
            obj = getattr(module, name, None)
            if obj is None or (module_name == "lagrax" and isinstance(obj, type(module))):
                continue
            path = f"{module_name}.{name}"
            paths[path] = obj
            if isinstance(obj, type):
                for member, value in vars(obj).items():
                    # the reference shows members with a docstring of their own
                    own_doc = isinstance(value, property | staticmethod | classmethod) or (
                        callable(value) and not isinstance(value, type)
                    )
                    if not member.startswith("_") and own_doc and getattr(value, "__doc__", None):
                        paths[f"{path}.{member}"] = getattr(obj, member, None)
    return paths


@functools.cache
def _public_path_of(obj_id: int) -> str | None:
    """The shortest public path of an object (``lagrax.X`` before ``lagrax.bodies.X``)."""
    found = [p for p, o in _public_objects().items() if id(o) == obj_id]
    return min(found, key=lambda p: (p.count("."), p)) if found else None


def _module_context(path: Path) -> list[str]:
    """Public modules a relative name in ``path`` is looked up in, most specific first.

    ``lagrax/bodies.py`` and ``lagrax/_bodies.py`` look in ``lagrax.bodies`` first,
    ``lagrax/models/_four_bar.py`` in ``lagrax.models``; then every public module."""
    rel = path.resolve().relative_to(ROOT).with_suffix("").parts
    first = []
    if len(rel) > 2 and f"lagrax.{rel[1]}" in PUBLIC_MODULES:
        first.append(f"lagrax.{rel[1]}")
    stem = rel[-1].lstrip("_")
    if f"lagrax.{stem}" in PUBLIC_MODULES:
        first.append(f"lagrax.{stem}")
    return [*dict.fromkeys([*first, *PUBLIC_MODULES])]


def resolve(name: str, modules: list[str], cls: str | None) -> str | None:
    """The documented public path that ``name`` (from a role) refers to, or None."""
    objects = _public_objects()
    name = name.lstrip(".")
    candidates = []
    if name.startswith("lagrax."):
        candidates.append(name)
    else:
        if cls is not None:
            for module in modules:
                candidates.append(f"{module}.{cls}.{name}")
        candidates.extend(f"{module}.{name}" for module in modules)
    for candidate in candidates:
        if candidate in objects:
            obj = objects[candidate]
            # an object of a module (not a member of a class) under its shortest public path
            if candidate.rsplit(".", 1)[0] in PUBLIC_MODULES and (
                isinstance(obj, type) or callable(obj)
            ):
                short = _public_path_of(id(obj))
                if short is not None and short.count(".") < candidate.count("."):
                    return short
            return candidate
    return None


def convert_role(match: re.Match, modules: list[str], cls: str | None) -> str:
    target = match.group(2).strip()
    titled = re.fullmatch(r"(.+?)\s*<([^>]+)>", target)  # :role:`title <target>`
    if titled is not None:
        shown, target = titled.group(1), titled.group(2).lstrip("~")
    else:
        short = target.startswith("~")
        target = target.lstrip("~")
        shown = target.rsplit(".", 1)[-1] if short else target
    full = resolve(target, modules, cls)
    if full is None:
        return f"`{shown}`"
    return f"[`{shown}`][]" if shown == full else f"[`{shown}`][{full}]"


# ---------------------------------------------------------------- text transforms


def convert_math(lines: list[str]) -> list[str]:
    out: list[str] = []
    i = 0
    while i < len(lines):
        m = MATH.match(lines[i])
        if m is None:
            out.append(lines[i])
            i += 1
            continue
        indent = m.group("indent")
        body: list[str] = [m.group("rest").strip()] if m.group("rest").strip() else []
        i += 1
        # the directive's content: following lines indented deeper, or blank
        while i < len(lines) and (
            not lines[i].strip() or len(lines[i]) - len(lines[i].lstrip()) > len(indent)
        ):
            body.append(lines[i].strip())
            i += 1
        while body and not body[-1]:
            body.pop()
        while body and not body[0]:
            body.pop(0)
        # one $$ block per paragraph of the directive
        paragraphs: list[list[str]] = [[]]
        for line in body:
            if line:
                paragraphs[-1].append(line)
            elif paragraphs[-1]:
                paragraphs.append([])
        if out and out[-1].strip():
            out.append("")
        for k, paragraph in enumerate(paragraphs):
            if k:
                out.append("")
            out.append(f"{indent}$$")
            out.extend(f"{indent}{line}" for line in paragraph)
            out.append(f"{indent}$$")
        if i < len(lines) and lines[i].strip():
            out.append("")
    return out


def separate_lists(lines: list[str]) -> list[str]:
    """Insert a blank line where a list starts right after a paragraph line."""
    out: list[str] = []
    in_list_indent: int | None = None  # indent of the current list's markers
    in_fence = False
    for line in lines:
        stripped = line.strip()
        if stripped.startswith("```"):
            in_fence = not in_fence
            in_list_indent = None
            out.append(line)
            continue
        if in_fence or not stripped:
            out.append(line)
            continue
        indent = len(line) - len(line.lstrip())
        item = LIST_ITEM.match(line)
        if item is not None:
            previous = out[-1] if out else ""
            if previous.strip() and (in_list_indent is None or indent < in_list_indent):
                if not previous.strip().endswith(('"""', "'''")):  # the docstring's opening
                    out.append("")
            if in_list_indent is None or indent < in_list_indent:
                in_list_indent = indent
        elif in_list_indent is not None and indent <= in_list_indent:
            in_list_indent = None
        out.append(line)
    return out


def _continues(line: str, indent: int) -> bool:
    """Whether ``line`` continues a paragraph whose lines start at ``indent``."""
    stripped = line.strip()
    return (
        bool(stripped)
        and len(line) - len(line.lstrip()) == indent
        and LIST_ITEM.match(line) is None
        and not stripped.startswith(("```", "$$", "**", '"""', "'''"))
    )


def rewrap_long_lines(
    lines: list[str], first: int, base: int, width: int = LINE_LENGTH
) -> list[str]:
    """Break lines longer than ``width`` (cross-references are longer than the roles they
    replace), carrying the rest into the paragraph's next lines. ``first`` is the column
    the docstring's text starts at, ``base`` its indentation. Lines in code fences and
    math blocks, and lines without a space to break at, stay."""
    out = list(lines)
    in_block = False
    i = 0
    while i < len(out):
        line = out[i]
        stripped = line.strip()
        if stripped.startswith("```") or stripped == "$$":
            in_block = not in_block
        limit = width - (3 if i == len(out) - 1 else 0)  # the closing quotes
        if i == 0:
            limit -= first
        if in_block or len(line) <= limit:
            i += 1
            continue
        indent = len(line) - len(line.lstrip())
        item = LIST_ITEM.match(line)
        cont = indent + 2 if item is not None else indent  # this paragraph's next lines
        if i == 0:
            cont = base
        cut = line.rfind(" ", indent + 1, limit + 1)
        if cut <= indent or (item is not None and cut <= indent + 2):
            i += 1
            continue
        head, rest = line[:cut], line[cut + 1 :]
        out[i] = head
        if i + 1 < len(out) and _continues(out[i + 1], cont):
            out[i + 1] = " " * cont + rest + " " + out[i + 1].strip()
        else:
            out.insert(i + 1, " " * cont + rest)
        i += 1
    return out


def convert_text(
    text: str, modules: list[str], cls: str | None, first: int = 0, base: int = 0
) -> str:
    text = ROLE.sub(lambda m: convert_role(m, modules, cls), text)
    text = LITERAL.sub(lambda m: f"`{m.group(1)}`", text)
    lines = text.split("\n")
    lines = convert_math(lines)
    lines = separate_lists(lines)
    lines = rewrap_long_lines(lines, first, base)
    return "\n".join(lines)


# ---------------------------------------------------------------- docstrings of a file


def _docstring_nodes(tree: ast.Module):
    """(string node, enclosing class name or None) for every docstring in the module."""

    def visit(body, cls):
        for stmt in body:
            if (
                isinstance(stmt, ast.Expr)
                and isinstance(stmt.value, ast.Constant)
                and isinstance(stmt.value.value, str)
            ):
                yield stmt.value, cls
            if isinstance(stmt, ast.ClassDef):
                yield from visit(stmt.body, stmt.name)
            elif isinstance(stmt, ast.FunctionDef | ast.AsyncFunctionDef):
                yield from visit(stmt.body, cls)

    yield from visit(tree.body, None)


def convert_source(source: str, path: Path) -> str:
    tree = ast.parse(source)
    lines = source.splitlines(keepends=True)
    line_starts = [0]
    for line in lines:
        line_starts.append(line_starts[-1] + len(line))

    def offset(lineno: int, col: int) -> int:  # ast's columns count UTF-8 bytes
        return line_starts[lineno - 1] + len(lines[lineno - 1].encode()[:col].decode())

    modules = _module_context(path)
    edits = []
    for node, cls in _docstring_nodes(tree):
        assert node.end_lineno is not None and node.end_col_offset is not None
        start = offset(node.lineno, node.col_offset)
        end = offset(node.end_lineno, node.end_col_offset)
        literal = source[start:end]
        m = re.match(r'(?s)^([rRuU]*)("""|\'\'\'|"|\')(.*)\2$', literal)
        if m is None:  # implicit concatenation or an f-string: leave alone
            continue
        prefix, quote, body = m.groups()
        column = start - line_starts[node.lineno - 1]
        first = column + len(prefix) + len(quote)
        new_body = convert_text(body, modules, cls, first, column)
        if new_body != body:
            edits.append((start, end, f"{prefix}{quote}{new_body}{quote}"))
    for start, end, new in reversed(edits):
        source = source[:start] + new + source[end:]
    return source


def default_paths() -> list[Path]:
    files = []
    for path in sorted((ROOT / "lagrax").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel in EXCLUDE or rel.startswith(EXCLUDE_DIRS):
            continue
        files.append(path)
    return files


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument(
        "paths",
        nargs="*",
        type=Path,
        help="files to convert (default: lagrax/ except the files in EXCLUDE)",
    )
    parser.add_argument(
        "--check", action="store_true", help="write nothing; exit 1 if a file would change"
    )
    parser.add_argument("--diff", action="store_true", help="with --check, print the diff")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    changed = []
    for path in args.paths or default_paths():
        source = path.read_text()
        new = convert_source(source, path)
        if new == source:
            continue
        changed.append(path)
        if args.check:
            if args.diff:
                sys.stdout.writelines(
                    difflib.unified_diff(
                        source.splitlines(keepends=True),
                        new.splitlines(keepends=True),
                        str(path),
                        str(path),
                    )
                )
        else:
            path.write_text(new)
    verb = "would change" if args.check else "changed"
    for path in changed:
        print(f"{verb}: {path}")
    print(f"{len(changed)} file(s) {verb}")
    return 1 if (args.check and changed) else 0


if __name__ == "__main__":
    raise SystemExit(main())
