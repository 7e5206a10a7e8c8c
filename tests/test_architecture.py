"""The architecture contract, run with the test suite.

1. Layers: ``livedic.bench`` > ``livedic.stream`` > ``livedic.acquire`` > ``livedic.dic``; a
   lower layer never imports a higher one, not even inside a function.
2. No import cycles between the modules (and subpackages) of a package.
3. Nothing private crosses a package: a private module (``pkg._mod``) is imported
   only inside its own package, and a private name (``_name``) of a module only
   inside that module's package. A subpackage (``dic.search``, ``dic.subpixel``)
   is a package of its own here: ``dic.subpixel`` may not use what
   ``dic.search`` keeps private, while both may use what ``dic`` keeps private.

1, 2 and the private modules of 3 are import-linter contracts (``.importlinter`` at
the top of the repository; ``lint-imports`` checks them alone); the private names
are checked here on the source, as import-linter does not look at names.
Each test reports every violation in one message.
"""

import ast
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: pytest itself depends on tomli there
    import tomli as tomllib

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("livedic.dic", "livedic.acquire", "livedic.stream", "livedic.bench")


def test_import_contracts_hold():
    """Layers, no cycles inside a package, private modules kept inside theirs (import-linter)."""
    run = subprocess.run([sys.executable, "-c", "from importlinter.cli import lint_imports_command as c; c()",
                          str(REPO / ".importlinter"), "--no-cache", "--no-logo"],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    if run.returncode != 0:
        pytest.fail("the import contracts are broken:\n" + _broken_part(run.stdout + run.stderr), pytrace=False)


def test_no_private_name_crosses_a_package():
    """``from livedic.x.m import _name`` and ``m._name`` only inside the package that holds ``m``."""
    modules = _modules()
    violations = []
    for name, (path, package) in sorted(modules.items()):
        for line, target, private in _private_uses(path, name, package, modules):
            owner = modules[target][1] if target in modules else target.rpartition(".")[0]
            if not _inside(package, owner):
                violations.append(f"{path.relative_to(REPO)}:{line}: {name} uses {target}.{private}, "
                                  f"private to {owner}")
    if violations:
        pytest.fail(f"{len(violations)} private name(s) used outside their package (make the name public in a "
                    f"module both may import, or move the code):\n" + "\n".join(violations), pytrace=False)


def test_the_contract_sees_every_package():
    """The contract covers the code that exists: every livedic package is found, with its modules."""
    modules = _modules()
    for package in PACKAGES:
        assert package in modules and any(m.startswith(package + ".") for m in modules), package


def test_every_package_is_listed_for_the_wheel():
    """pyproject.toml lists every folder holding an ``__init__.py``, and nothing else.

    The editable install finds sub-packages through its folder mapping, so the tests pass
    even when a package is missing from ``packages``; a wheel built from the list would lack it.
    """
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    found = set()
    for package, folder in setuptools["package-dir"].items():
        root = REPO / folder
        found.update(".".join((package,) + init.parent.relative_to(root).parts) for init in root.rglob("__init__.py"))
    listed = set(setuptools["packages"])
    assert not found - listed, f"add to pyproject.toml [tool.setuptools] packages: {sorted(found - listed)}"
    assert not listed - found, f"listed in pyproject.toml but no such package: {sorted(listed - found)}"


# ---------------------------------------------------------------------------


def _broken_part(report):
    """The part of import-linter's report that says what is broken (all of it if it has none)."""
    start = report.find("Broken contracts")
    return report[start:] if start >= 0 else report


def _modules():
    """Module name -> (source path, package whose privacy it shares) for every livedic module."""
    modules = {}
    for package in PACKAGES:
        spec = importlib.util.find_spec(package)
        assert spec is not None and spec.submodule_search_locations, f"{package} is not importable"
        root = Path(list(spec.submodule_search_locations)[0])
        for path in root.rglob("*.py"):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[-1] == "__init__":
                name = ".".join((package,) + parts[:-1])
                modules[name] = (path, name)
            else:
                name = ".".join((package,) + parts)
                modules[name] = (path, name.rpartition(".")[0])
    return modules


def _is_private(name):
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _inside(package, owner):
    return package == owner or package.startswith(owner + ".")


def _private_uses(path, module, package, modules):
    """(line, module, private name) for each private name of a livedic module that ``path`` uses.

    ``from M import _x`` where ``M._x`` is not a module (importing a private module is
    import-linter's part), and ``M._x`` where ``M`` names a livedic module (an import's
    alias, or spelled out): a private name or module reached as an attribute.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    aliases = {}
    uses = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            source = _absolute(node, module, package)
            if source not in modules:
                continue
            for alias in node.names:
                target = f"{source}.{alias.name}"
                if target in modules:
                    aliases[alias.asname or alias.name] = target
                elif _is_private(alias.name):
                    uses.append((node.lineno, source, alias.name))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in modules and alias.asname:
                    aliases[alias.asname] = alias.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _is_private(node.attr):
            target = _dotted(node.value, aliases)
            if target in modules:
                uses.append((node.lineno, target, node.attr))
    return uses


def _absolute(node, module, package):
    """The module an ``ImportFrom`` node names, relative imports resolved."""
    if not node.level:
        return node.module
    base = package.split(".")
    if node.level > 1:
        base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _dotted(node, aliases):
    """``livedic.x.y`` for an expression naming a module (through an alias or spelled out), else None."""
    if isinstance(node, ast.Name):
        return aliases.get(node.id)
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value, aliases)
        if head is not None:
            return f"{head}.{node.attr}"
        parts = []
        while isinstance(node, ast.Attribute):
            parts.append(node.attr)
            node = node.value
        if isinstance(node, ast.Name) and node.id == "livedic":
            return ".".join(["livedic"] + parts[::-1])
    return None
