"""A traced Rig against the in-process fake joint node, each on a virtual bus of their own: what
the trace, diff and release tests run, opened and closed one way."""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Iterator

import can

from hilrig.engine.rig import Rig
from hilrig.observe.tracer import Tracer
from hilrig.plants import JointParams
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

_channels = itertools.count()


@contextlib.contextmanager
def traced_fake_rig(tracer: Tracer, table: RigTable) -> Iterator[Rig]:
    """A started Rig (the fast-thermal joint, seed 3) traced by `tracer` against the fake node;
    the rig, the node, the tracer and both buses closed in that order however the body ends."""
    channel = f"hilrig-fake-rig-{next(_channels)}"
    rig_bus, fake_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    fake = FakeJointNode(fake_bus, table=table)
    rig = Rig(
        rig_bus,
        table=table,
        params=JointParams.fast_thermal(),
        seed=3,
        tpdo_timeout_s=0.5,
        activity=fake.activity,
        tracer=tracer,
    )
    fake.boot()
    try:
        rig.start()
        yield rig
    finally:
        rig.close()
        fake.close()
        tracer.close()
        rig_bus.shutdown()
        fake_bus.shutdown()
