"""Fixtures for the hardware-in-the-loop scenarios: a private bus per test."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from hilrig.netns import PrivateBus, private_buses_supported


@pytest.fixture
def private_bus() -> Iterator[PrivateBus]:
    """A network namespace with its own vcan0, for this test alone."""
    if not private_buses_supported():
        pytest.fail(
            "bus-level scenarios need root and a kernel with vcan: run them with `make test` "
            "or `tools/with-vcan -- .venv/bin/pytest tests`",
            pytrace=False,
        )
    with PrivateBus() as bus:
        yield bus
