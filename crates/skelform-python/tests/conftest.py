import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[3]


@pytest.fixture
def examples():
    """The repository's example scenes."""
    return ROOT / "examples"
