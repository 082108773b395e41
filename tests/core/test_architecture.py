"""The import structure holds: no module imports one that imports it back, and the CLI
loads without torch (its training commands import it inside the command).

``lint-imports`` (.importlinter, run by scripts/test.sh) checks the layers and the
cycles between sibling modules; a package importing its own submodule that imports the
package back (``spacemesh.io`` and ``spacemesh.io.points`` once did) is no sibling cycle,
so the strongly connected components of the whole module graph are checked here.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import grimp
import pytest

from tests.factories import BLOCK_TORCH

PACKAGES = ("spacemesh", "spacemesh_service", "spacemesh_client")


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (iterative Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found: list[list[str]] = []
    counter = 0
    for root in sorted(edges):
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    component.append(top)
                    if top == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _graph() -> dict[str, set[str]]:
    graph = grimp.build_graph(*PACKAGES, exclude_type_checking_imports=True)
    return {module: set(graph.find_modules_directly_imported_by(module))
            for module in graph.modules}


def test_the_cycle_finder_finds_a_package_importing_its_child_back():
    edges = {"p": {"p.a"}, "p.a": {"p.b"}, "p.b": {"p"}, "q": {"p"}}
    assert _cycles(edges) == [["p", "p.a", "p.b"]]
    assert _cycles({"p": {"p.a"}, "p.a": set()}) == []


def test_no_module_imports_one_that_imports_it_back():
    assert _cycles(_graph()) == []


def test_lint_imports_contracts_hold():
    lint = Path(sys.executable).with_name("lint-imports")
    if not lint.exists():
        pytest.fail(f"{lint} is missing: install import-linter (the test extra)")
    done = subprocess.run([str(lint), "--no-cache"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]


def test_the_cli_loads_and_lists_its_commands_without_torch():
    script = BLOCK_TORCH + r"""
from typer.testing import CliRunner
from spacemesh.cli import _register
from spacemesh.cli.common import app
_register()
result = CliRunner().invoke(app, ["--help"])
assert result.exit_code == 0, result.output
assert "train" in result.output and "generate" in result.output
assert "torch" not in sys.modules
print("ok")
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().endswith("ok")
