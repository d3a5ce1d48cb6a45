"""Fixtures of the protocol tests (the vector files, read once per session)."""

from __future__ import annotations

import pytest
from vector_files import StreamVector, Vector, load_golden, load_streams


@pytest.fixture(scope="session")
def golden() -> list[Vector]:
    return load_golden()


@pytest.fixture(scope="session")
def stream_vectors() -> list[StreamVector]:
    return load_streams()
