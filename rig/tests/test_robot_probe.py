"""The robot's one exchange per cycle (`hilrig.engine.robot`), natively, on the rig probe's
(`hilrig.apps.bench.probe`) answering raw-socket peers (fake nodes for the start-up over SDO): a
module whose process is gone and whose TPDOs stop is lost at that cycle, the others run on. The
same as tests/test_robot.py's killed module against the firmware in the VM, in a few seconds and
without a bus."""

from __future__ import annotations

import contextlib
import socket
from typing import Any

import pytest

from hilrig.apps.bench import probe as rig_probe


class QuietWhenAsked(rig_probe.AnsweringLink):  # type: ignore[misc, name-defined]
    """The probe's answering peer, silent for the COB-IDs it has no answer for (a dead node's)."""

    def exchange(self, out, due, decoders, got, timeout_s, cycle=None):  # type: ignore[no-untyped-def]
        for cob_id in due:
            if cob_id in self.answers and cob_id not in got:
                self._peer.send(self.answers[cob_id])
        result = rig_probe.RawCanLink.exchange(self, out, due, decoders, got, timeout_s, cycle)
        with contextlib.suppress(BlockingIOError):
            while True:
                self._peer.recv(16, socket.MSG_DONTWAIT)
        return result


def test_a_module_whose_process_died_is_lost_at_that_cycle_and_the_others_run_on() -> None:
    import can

    from hilrig.apps.gait import TravellingWave
    from hilrig.engine.rig import Rig
    from hilrig.engine.robot import Robot, RobotObserver
    from hilrig.errors import FirmwareError
    from hilrig.plants.chain import ChainPhysics
    from hilrig.session.fake_node import FakeJointNode
    from hilrig.table import RigTable
    from hilrig.wire.transport import can_frame

    class Events(RobotObserver):
        def __init__(self) -> None:
            self.events: list[tuple[int, str]] = []

        def on_robot_event(self, text: str, *, warning: bool, cycle: int, t: float) -> None:
            self.events.append((cycle, text))

    table = RigTable.load()
    chain = ChainPhysics(3)
    answers: dict[int, bytes] = {}
    with contextlib.ExitStack() as stack:
        rigs: list[Any] = []
        fakes = []
        for k, node_id in enumerate((1, 2, 3)):
            node_bus = stack.enter_context(can.Bus(interface="virtual", channel="lost"))
            fake = FakeJointNode(node_bus, table=table, node_id=node_id)
            fake.boot()
            fakes.append(fake)
            ours, peer = rig_probe._socket_pair()
            stack.callback(ours.close)
            stack.callback(peer.close)
            link = QuietWhenAsked(ours, peer, answers)
            bus = stack.enter_context(can.Bus(interface="virtual", channel="lost"))
            rig = Rig(bus, table=table, node_id=node_id, plant=chain.models[k])
            rig.node.open_link = lambda receive_ids, link=link: link  # type: ignore[method-assign]
            stack.callback(rig.close)
            rigs.append(rig)
        robot = Robot(rigs, chain)
        events = Events()
        robot.add_observer(events)
        robot.start()
        TravellingWave().drive(robot)
        for fake, rig in zip(fakes, rigs, strict=True):
            fake.close()  # from here on the link's peer is the node
            tpdos = [p for p in rig.node.tpdos.values() if p.enabled and p.names]
            answers.update({p.cob_id: can_frame(p.cob_id, bytes(p.length)) for p in tpdos})
        robot.run(cycles=50)
        dead = rigs[1]
        for pdo in dead.node.tpdos.values():
            answers.pop(pdo.cob_id, None)

        def gone() -> None:
            raise FirmwareError("firmware exited (SIGKILL)")

        dead.driver.liveness = gone
        robot.run(cycles=10)
        assert list(robot.lost) == [2]
        lost = robot.lost[2]
        assert (lost.cycle, lost.reason) == (50, "firmware exited (SIGKILL)")
        assert events.events == [(50, str(lost))]
        t, _ = dead.history("output_position")
        assert t[-1] == pytest.approx(49 * robot.period_s), "nothing of the dead module from then on"
        assert len(dead.truth("applied_duty")[0]) == 60, "the limp joint still has a truth every cycle"
        for rig in (rigs[0], rigs[2]):
            t, _ = rig.history("output_position")
            assert t[-1] == pytest.approx(59 * robot.period_s)
