"""The house-rules check (tools/house_rules.py) finds each breach it is there for, and
the package as it stands has none."""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def rules():
    spec = importlib.util.spec_from_file_location("house_rules", ROOT / "tools" / "house_rules.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["house_rules"] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("house_rules", None)


def _package(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = tmp_path / "lagrax" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return tmp_path


def test_the_package_keeps_the_rules(rules, capsys):
    assert rules.main(["house_rules", str(ROOT)]) == 0, capsys.readouterr().out


def test_a_private_name_imported_from_another_module_is_a_breach(rules, capsys, tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "",
            "_wing/__init__.py": "",
            "_wing/low.py": "def _helper():\n    return 1\n\ndef public():\n    return 2\n",
            "_wing/high.py": "from .low import _helper, public\n",
            # a private *module* is how a wing is reached: allowed
            "face.py": "from ._wing import low\nfrom . import _wing\n",
        },
    )
    assert rules.main(["house_rules", str(root)]) == 1
    out = capsys.readouterr().out
    assert "imports the private name lagrax._wing.low._helper" in out
    assert "public" not in out and "face.py" not in out


def test_long_modules_and_functions_are_breaches(rules, capsys, tmp_path):
    n = rules.MAX_FUNCTION_LINES + 1
    body = "".join(f"    x{i} = {i}\n" for i in range(n))
    # a docstring, comments and blank lines do not count
    short = (
        'def short():\n    """' + "doc\n" * 200 + '"""\n' + "    # note\n\n" * 50 + "    return 0\n"
    )
    root = _package(
        tmp_path,
        {
            "__init__.py": "",
            "long.py": f"def long():\n{body}    return 0\n",
            "fine.py": short,
            "big.py": "x = 1\n" * (rules.MAX_MODULE_LINES + 1),
        },
    )
    assert rules.main(["house_rules", str(root)]) == 1
    out = capsys.readouterr().out
    assert f"long has {n + 2} code lines" in out
    assert "short" not in out
    assert f"big.py: {rules.MAX_MODULE_LINES + 1} lines" in out


def test_a_builtin_exception_raised_is_a_breach(rules, capsys, tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": (
                # Python's protocol: a module's __getattr__ raises AttributeError
                "def __getattr__(name):\n    raise AttributeError(name)\n"
            ),
            "bad.py": (
                "import builtins\n"
                "def f(kind):\n"
                "    if kind == 1:\n"
                "        raise ValueError(kind)\n"
                "    if kind == 2:\n"
                "        raise NotImplementedError\n"
                "    if kind == 3:\n"
                "        raise builtins.FileNotFoundError('x') from None\n"
                "    def __getattr__(name):\n"  # the exemption is AttributeError only
                "        raise KeyError(name)\n"
                "    raise AttributeError(kind)\n"
            ),
            "good.py": (
                "from typing import assert_never\n"
                "from lagrax._core.errors import ConfigurationError\n"
                "class LocalError(Exception):\n    pass\n"
                "def g(kind, err):\n"
                "    if kind == 1:\n"
                "        raise ConfigurationError(f'kind={kind!r}')\n"
                "    if kind == 2:\n"
                "        raise err\n"
                "    if kind == 3:\n"
                "        raise\n"
                "    if kind == 4:\n"
                "        raise LocalError(kind)\n"
                "    assert_never(kind)\n"
            ),
        },
    )
    assert rules.main(["house_rules", str(root)]) == 1
    out = capsys.readouterr().out
    for line, name in [(4, "ValueError"), (6, "NotImplementedError"), (8, "FileNotFoundError")]:
        assert f"bad.py:{line}: raises the builtin {name}" in out
    assert "bad.py:10: raises the builtin KeyError" in out
    assert "bad.py:11: raises the builtin AttributeError" in out
    assert "good.py" not in out and "__init__.py" not in out
    assert "house rules: 5 breach(es)" in out


def test_hasattr_is_a_breach(rules, capsys, tmp_path):
    root = _package(
        tmp_path,
        {
            "__init__.py": "",
            "view.py": (
                "def draw(tree):\n"
                "    if not hasattr(tree, 'body_names'):\n"
                "        return None\n"
                "    return [hasattr(b, 'n') for b in tree.bodies]\n"
            ),
            # reading another library's optional attribute, and isinstance, are the ways
            "fine.py": (
                "def read(model, tree_class, tree):\n"
                "    values = getattr(model, 'jnt_springyield', None)\n"
                "    return values, isinstance(tree, tree_class)\n"
            ),
        },
    )
    assert rules.main(["house_rules", str(root)]) == 1
    out = capsys.readouterr().out
    assert "view.py:2: hasattr" in out and "view.py:4: hasattr" in out
    assert "fine.py" not in out
    assert "house rules: 2 breach(es)" in out
