#!/usr/bin/env python3
"""The house's measures: how large its files and functions are, how much is typed, how the tests wait.

Reads the source tree as text (the standard library only, nothing is imported or run), so it measures any
commit: ``git worktree add /tmp/old REV && python3 scripts/house_metrics.py --root /tmp/old``.
The targets are those of the code-organisation issue (docs/guide/dev/architecture.md#measures).

    python3 scripts/house_metrics.py [--root DIR] [--list]
"""

from __future__ import annotations

import argparse
import ast
import re
from dataclasses import dataclass
from pathlib import Path

PACKAGES = ("dic", "acquire", "stream", "bench")
TYPED_PACKAGES = ("dic", "acquire", "stream")
LONG_FILE = 800
MEDIUM_FILE = 500
LONG_FUNCTION = 80
SUBPIXEL_NAMES = {"icgn", "icgn2", "newton-raphson", "improved-surface-fit", "surface-fit",
                  "gradient", "centroid", "none"}
BRANCHING_MODULES = re.compile(r"dic/(tracking|measure|key_frames)")


@dataclass
class Function:
    path: str
    name: str
    lines: int
    public: bool
    annotated: bool
    numba: bool


def _is_numba(node: ast.AST) -> bool:
    for deco in getattr(node, "decorator_list", []):
        text = ast.unparse(deco)
        if re.search(r"\b(njit|jit|vectorize|guvectorize|stencil)\b", text):
            return True
    return False


def _annotated(node: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> bool:
    args = node.args
    params = args.posonlyargs + args.args + args.kwonlyargs
    if method and params and params[0].arg in ("self", "cls"):
        params = params[1:]
    extra = [a for a in (args.vararg, args.kwarg) if a is not None]
    typed_params = all(a.annotation is not None for a in params + extra)
    returns = node.returns is not None or node.name == "__init__"
    return typed_params and returns


def functions(path: Path, rel: str) -> list[Function]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found: list[Function] = []

    def visit(body: list[ast.stmt], in_class: bool, public_scope: bool) -> None:
        for node in body:
            if isinstance(node, ast.ClassDef):
                visit(node.body, True, public_scope and not node.name.startswith("_"))
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                dunder = node.name.startswith("__") and node.name.endswith("__")
                public = public_scope and (not node.name.startswith("_") or node.name == "__init__")
                found.append(Function(rel, node.name, node.end_lineno - node.lineno + 1,
                                      public and (not dunder or node.name == "__init__"),
                                      _annotated(node, in_class), _is_numba(node)))
                visit(node.body, False, False)

    visit(tree.body, False, True)
    return found


def method_name_branches(path: Path) -> int:
    """Comparisons of a value with a sub-pixel method's name (`x == "icgn2"`, `x in ("icgn", ...)`)."""
    count = 0
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Compare):
            for comp in [node.left, *node.comparators]:
                values = comp.elts if isinstance(comp, (ast.Tuple, ast.Set, ast.List)) else [comp]
                if any(isinstance(v, ast.Constant) and v.value in SUBPIXEL_NAMES for v in values):
                    count += 1
                    break
    return count


def tested_modules(root: Path) -> tuple[int, list[str]]:
    """How many modules of dic, acquire and stream that define a function or class have a test module of their
    name in the mirrored folder of tests/ (``tests/acquire/recording/test_writer*.py`` for
    ``acquire/recording/writer.py``), and the paths of those that have none."""
    found, missing = 0, []
    for package in TYPED_PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            if path.name == "__init__.py":
                continue
            tree = ast.parse(path.read_text(encoding="utf-8"))
            if not any(isinstance(n, (ast.FunctionDef, ast.ClassDef)) for n in tree.body):
                continue
            folder = root / "tests" / path.parent.relative_to(root)
            if any(folder.glob(f"test_{path.stem.lstrip('_')}*.py")):
                found += 1
            else:
                missing.append(str(path.relative_to(root)))
    return found, missing


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent)
    parser.add_argument("--list", action="store_true", help="name the long files and functions")
    args = parser.parse_args()
    root = args.root

    sizes: dict[str, int] = {}
    funcs: list[Function] = []
    branches = 0
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            rel = str(path.relative_to(root))
            sizes[rel] = len(path.read_text(encoding="utf-8").splitlines())
            funcs += functions(path, rel)
            if BRANCHING_MODULES.match(rel):
                branches += method_name_branches(path)

    long_files = sorted(((n, p) for p, n in sizes.items() if n > LONG_FILE), reverse=True)
    long_funcs = sorted(((f.lines, f.path, f.name) for f in funcs
                         if f.lines > LONG_FUNCTION and not f.numba), reverse=True)
    # numba kernels are left out: numba infers their types, and annotations there would be ignored
    typed = [f for f in funcs if f.public and not f.numba and f.path.split("/")[0] in TYPED_PACKAGES]
    test_files = list((root / "tests").rglob("*.py"))
    sleeps = sum(len(re.findall(r"\btime\.sleep\(", p.read_text(encoding="utf-8")))
                 for p in test_files)
    mirrored, unmirrored = tested_modules(root)
    readme = root / "README.md"
    readme_lines = len(readme.read_text(encoding="utf-8").splitlines()) if readme.exists() else 0

    rows = [
        ("source files (dic, acquire, stream, bench)", f"{len(sizes)}", ""),
        ("source lines", f"{sum(sizes.values()):,}", ""),
        (f"files over {LONG_FILE} lines", f"{len(long_files)}", "at most 3"),
        (f"files over {MEDIUM_FILE} lines", f"{sum(n > MEDIUM_FILE for n in sizes.values())}", ""),
        (f"functions over {LONG_FUNCTION} lines (numba kernels aside)", f"{len(long_funcs)}", "at most 6"),
        ("public functions and methods annotated (dic, acquire, stream)",
         f"{sum(f.annotated for f in typed)} of {len(typed)} "
         f"({100 * sum(f.annotated for f in typed) / max(len(typed), 1):.0f} %)", "80 %"),
        ("sub-pixel method-name branches in tracking, measure, key frames", f"{branches}", "0"),
        ("source modules with logic that have a test module of their name",
         f"{mirrored} of {mirrored + len(unmirrored)}", "all"),
        ("README lines", f"{readme_lines}", "about 200"),
        ("time.sleep calls in the tests", f"{sleeps}", "at most 10"),
        ("test lines", f"{sum(len(p.read_text(encoding='utf-8').splitlines()) for p in test_files):,}", ""),
    ]
    width = max(len(r[0]) for r in rows)
    print(f"{'measure':<{width}}  {'value':>16}  target")
    for name, value, target in rows:
        print(f"{name:<{width}}  {value:>16}  {target}")
    if args.list:
        print("\nfiles over", LONG_FILE, "lines:")
        for n, p in long_files:
            print(f"  {n:5d} {p}")
        print("\nsource modules with logic and no test module of their name (tests/<same folders>/test_<name>*.py):")
        for path in unmirrored:
            print(f"  {path}")
        print("\nfunctions over", LONG_FUNCTION, "lines:")
        for n, p, name in long_funcs:
            print(f"  {n:5d} {p} {name}")


if __name__ == "__main__":
    main()
