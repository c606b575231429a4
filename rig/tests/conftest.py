"""Fixtures shared by the rig's unit tests: the in-process fake joint node on a virtual bus."""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import can
import pytest

from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

_channels = itertools.count()


@pytest.fixture
def channel() -> str:
    """A virtual bus channel of this test alone."""
    return f"rig-test-{next(_channels)}"


@pytest.fixture
def fake(channel: str) -> Iterator[FakeJointNode]:
    """The fake joint node, booted (pre-operational), on `channel` of the virtual bus."""
    bus = can.Bus(interface="virtual", channel=channel)
    node = FakeJointNode(bus, table=RigTable.load())
    node.boot()
    try:
        yield node
    finally:
        node.close()
        bus.shutdown()
