from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SYSTEMS = sorted((ROOT / "systems").glob("*.yaml"))


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--update-golden", action="store_true", help="rewrite tests/golden/ from the current output")


@pytest.fixture
def update_golden(request: pytest.FixtureRequest) -> bool:
    return bool(request.config.getoption("--update-golden"))


@pytest.fixture(scope="module")
def private_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """Generated modules and machine code go to a directory of this test module (use with
    `pytestmark = pytest.mark.usefixtures("private_cache")`)."""
    patch = pytest.MonkeyPatch()
    patch.setenv("LAGRANGE_CACHE_DIR", str(tmp_path_factory.mktemp("lagrange-cache")))
    yield
    patch.undo()
