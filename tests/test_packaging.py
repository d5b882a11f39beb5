"""What the wheel ships: the four product packages and nothing of the test suite or the benches.

`tests` used to be installed because the benches imported helpers from it; those helpers now live in
`bench/support` (a plain folder, never installed) and both the benches and the suite import them from there. These
tests read the package list exactly as setuptools does from pyproject.toml, check that no product module needs
`tests` or `bench` at run time, and import every bench script in a child process that refuses any `tests` import,
so a bench that reaches into the suite again fails here rather than on an installed gateway."""
from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import setuptools

ROOT = Path(__file__).resolve().parents[1]
PRODUCT = {"engine", "firmware_protocol", "gateway", "gui"}


def shipped_packages() -> list[str]:
    """The packages setuptools puts in the wheel, from pyproject's own find settings (namespaces on by default)."""
    find = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]["find"]
    finder = setuptools.find_namespace_packages if find.get("namespaces", True) else setuptools.find_packages
    return finder(where=str(ROOT / find.get("where", ["."])[0]), include=find.get("include", ["*"]),
                  exclude=find.get("exclude", ()))


def test_the_wheel_ships_the_product_packages_and_no_tests_or_bench():
    shipped = shipped_packages()
    tops = {name.split(".")[0] for name in shipped}
    assert tops == PRODUCT, sorted(tops)
    # the discovery is really what keeps them out: both folders exist and are importable packages
    assert (ROOT / "tests" / "__init__.py").is_file() and (ROOT / "bench" / "support" / "__init__.py").is_file()
    assert "gateway.calibration" in shipped and "firmware_protocol.emulator" in shipped
    assert setuptools.find_namespace_packages(where=str(ROOT), include=["tests*"]), "tests/ no longer a package?"


def test_no_product_module_imports_tests_or_bench():
    offenders = []
    for top in sorted(PRODUCT):
        for path in (ROOT / top).rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
                names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                         else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
                offenders += [f"{path.relative_to(ROOT)}:{node.lineno} {n}" for n in names
                              if n.split(".")[0] in ("tests", "bench")]
    assert not offenders, offenders


# Runs in a child: refuse `tests`/`conftest` imports, load every bench script's module level (imports and
# definitions; `run_name` is not "__main__", so no benchmark runs) and report what failed and which modules of
# the test folder ended up loaded anyway.
_IMPORT_EVERY_BENCH = r"""
import importlib.abc, json, runpy, sys, traceback
from pathlib import Path

root, scripts = Path(sys.argv[1]), sys.argv[2:]

class RefuseTests(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "tests" or name.startswith("tests.") or name == "conftest":
            raise ImportError(f"bench imported the test suite: {name}")
        return None

sys.meta_path.insert(0, RefuseTests())
failed = {}
for script in scripts:
    try:
        runpy.run_path(script, run_name="bench_import_check")
    except BaseException:
        failed[Path(script).name] = traceback.format_exc(limit=3)
from_tests = sorted(name for name, mod in list(sys.modules.items())
                    if str(getattr(mod, "__file__", None) or "").startswith(str(root / "tests")))
print(json.dumps({"failed": failed, "from_tests": from_tests}))
"""


def test_every_bench_script_imports_without_the_test_suite(tmp_path):
    scripts = sorted(str(p) for p in (ROOT / "bench").glob("bench_*.py"))
    assert len(scripts) >= 20, scripts
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen", "PYTHONPATH": str(ROOT)}
    # from an unrelated folder, so only the scripts' own path setup and PYTHONPATH can find anything
    out = subprocess.run([sys.executable, "-c", _IMPORT_EVERY_BENCH, str(ROOT), *scripts], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    report = json.loads(out.stdout.strip().splitlines()[-1])
    assert report["failed"] == {}, "\n".join(f"{k}:\n{v}" for k, v in report["failed"].items())
    assert report["from_tests"] == []
