"""The layout of tests and benchmarks (issue 11): what they share lives in ``tests/helpers.py``
(for tests) or in the package, :mod:`daskrad.testing` (for both); a test module imports no other
test module, and a benchmark imports nothing of ``tests``. The package's own layering is checked
by import-linter (``make lint``), which does not see these two directories.
"""

from __future__ import annotations

import ast

import pytest

from tests.helpers import REPO


def imported_modules(path):
    """Every module an ``import`` or ``from … import`` of the file names, at any depth (imports
    inside functions included); ``from tests import x`` gives ``tests.x``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
    return out


def _files(directory):
    return sorted((REPO / directory).glob("*.py"))


@pytest.mark.parametrize("path", _files("tests"), ids=lambda p: p.name)
def test_tests_share_through_helpers_only(path):
    other = {m for m in imported_modules(path) if m.split(".")[0] == "tests"
             and m != "tests" and m.split(".")[:2] != ["tests", "helpers"]}
    assert not other, f"{path.name} imports {sorted(other)}"


@pytest.mark.parametrize("path", _files("benchmarks"), ids=lambda p: p.name)
def test_benchmarks_import_nothing_of_tests(path):
    from_tests = {m for m in imported_modules(path) if m.split(".")[0] == "tests"}
    assert not from_tests, f"{path.name} imports {sorted(from_tests)}"


def test_the_checks_see_a_test_module_import(tmp_path):
    # the detector itself: a cross-import of test modules and one inside a function are found
    f = tmp_path / "t.py"
    f.write_text("from tests.test_direct import x\ndef g():\n    from tests import stress_cases\n")
    assert {"tests.test_direct", "tests.stress_cases"} <= imported_modules(f)


def private_uses(path):
    """Names with a leading underscore that the file takes from daskrad: ``from daskrad.x
    import _y`` and ``alias._y`` where ``alias`` names a daskrad module or object imported
    into the file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    aliases, out = set(), set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("daskrad"):
            for a in node.names:
                if a.name.startswith("_"):
                    out.add(f"{node.module}.{a.name}")
                aliases.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            aliases.update(a.asname or a.name.split(".")[0] for a in node.names
                           if a.name.startswith("daskrad"))
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                and not node.attr.startswith("__") and isinstance(node.value, ast.Name)
                and node.value.id in aliases):
            out.add(f"{node.value.id}.{node.attr}")
    return out


@pytest.mark.parametrize("path", _files("tests") + _files("benchmarks"),
                         ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_private_names_of_the_package(path):
    assert not private_uses(path), f"{path.name} uses {sorted(private_uses(path))}"


def test_the_private_check_sees_private_names(tmp_path):
    f = tmp_path / "t.py"
    f.write_text("from daskrad.run import _camera\nfrom daskrad.formfactor import shooting\n"
                 "x = shooting._strata(2)\n")
    assert private_uses(f) == {"daskrad.run._camera", "shooting._strata"}
