"""The import structure holds: no module imports one that imports it back (type-only
imports under ``if TYPE_CHECKING:`` included), no module is over :data:`MAX_MODULE_LINES`
lines, and the CLI loads without torch (its training commands import it inside the
command).

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
#: The package folders of the repository.
PACKAGE_DIRS = ("model/spacemesh", "service/spacemesh_service", "client/spacemesh_client")
#: Most lines of a hand-written module (a longer one does more than one job: split it).
MAX_MODULE_LINES = 800
#: Generated modules, exempt from the size limit (protobuf and gRPC stubs).
GENERATED = ("_pb2.py", "_pb2_grpc.py", "_pb2.pyi")
ROOT = Path(__file__).resolve().parents[2]


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
    # a type-only import still ties two modules together: it counts
    graph = grimp.build_graph(*PACKAGES, exclude_type_checking_imports=False)
    return {module: set(graph.find_modules_directly_imported_by(module))
            for module in graph.modules}


def test_the_cycle_finder_finds_a_package_importing_its_child_back():
    edges = {"p": {"p.a"}, "p.a": {"p.b"}, "p.b": {"p"}, "q": {"p"}}
    assert _cycles(edges) == [["p", "p.a", "p.b"]]
    assert _cycles({"p": {"p.a"}, "p.a": set()}) == []


def test_no_module_imports_one_that_imports_it_back():
    assert _cycles(_graph()) == []


def test_type_only_imports_count_as_imports():
    graph = _graph()
    # spacemesh.cli.common imports GenerateOptions under `if TYPE_CHECKING:` only
    assert "TYPE_CHECKING:\n    from spacemesh.runtime.options import GenerateOptions" in (
        ROOT / "model/spacemesh/cli/common.py").read_text()
    assert "spacemesh.runtime.options" in graph["spacemesh.cli.common"]


def test_no_module_is_over_the_size_limit():
    modules = [path for folder in PACKAGE_DIRS for path in (ROOT / folder).rglob("*.py")]
    assert len(modules) > 100
    over = {str(path.relative_to(ROOT)): lines for path in modules
            if not path.name.endswith(GENERATED)
            and (lines := len(path.read_text().splitlines())) > MAX_MODULE_LINES}
    assert over == {}, f"modules over {MAX_MODULE_LINES} lines: {over}"


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
