"""The package's folders form a stack: each imports only the folders below it (and itself)."""
import ast
from pathlib import Path

import pytest

pytestmark = pytest.mark.fast

PACKAGE = Path(__file__).resolve().parents[1] / "signorini_cli"
# bottom to top: the walk of a config from YAML to table
FLOORS = ("system", "config", "analysis", "meshing", "solve", "problems", "studies", "record", "report", "app")


def imported_folders(path):
    """The package folders a module imports (relative imports, also inside functions)."""
    folder = path.parent.name
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            if node.level == 1:
                found.add(folder)
            elif node.module:
                found.add(node.module.split(".")[0])
            else:
                found.update(alias.name for alias in node.names if alias.name in FLOORS)
    return found


@pytest.mark.parametrize("folder", FLOORS)
def test_folder_imports_only_below(folder):
    above = set(FLOORS[FLOORS.index(folder) + 1:])
    for path in sorted((PACKAGE / folder).glob("*.py")):
        assert not imported_folders(path) & above, path.relative_to(PACKAGE)


def test_every_folder_has_a_floor():
    folders = {p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert folders == set(FLOORS)
