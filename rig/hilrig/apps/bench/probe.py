"""The Rig's own cost per lockstep cycle, natively and deterministically (`make bench` runs it).

The VM's cycles per second move by 10-20 % between runs of the same code; these do not:

    python tools/rig_probe.py rig CYCLES      # the full Rig (physics, history, checks)
    python tools/rig_probe.py fmu CYCLES      # the same with the joint's FMU as its plant
                                              # (build/fmu/joint.fmu of `make build`, over FMPy)
    python tools/rig_probe.py engine CYCLES   # the engine's exchange alone, same frames
    python tools/rig_probe.py memory CYCLES   # bytes the Rig keeps per cycle (tracemalloc), and
                                              # the data bytes the bus carried
    python tools/rig_probe.py traced CYCLES   # the full Rig traced to a .rrd, close() included
    python tools/rig_probe.py tracer-idle CYCLES  # the same Tracer made and closed, not attached
    python tools/rig_probe.py robot CYCLES --modules N  # a `Robot` of N modules on the MuJoCo
                                              # chain following the gait, untraced

`make bench` runs the first three under callgrind at two lengths, so start-up cancels out, and
reports instructions per cycle of the main thread; and the last two at one length, counting every
thread (the sender, Rerun's encoder and file writer): their difference is what tracing those
cycles costs, from naming the series to the file's footer, whatever runs in parallel.

All run over a raw-socket link (an AF_UNIX SOCK_SEQPACKET pair, the C exchange as on SocketCAN)
whose peer answers at once: before each exchange it queues every TPDO due at that SYNC (zero
payloads of the mapped lengths), after it takes what the rig sent. The node's PDO configuration
comes from the fake node over canopen's SDO, as on a bus; no firmware, no bus, no waiting, so
nothing depends on timing. With zero payloads the motor's duty is 0 and it stands still: the
traced series hold their values, which Rerun compresses better than moving ones (a trace of
`make bench`, whose VM rounds drive the motor, is larger than one of a still motor), so `traced`
counts what tracing costs at the least.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import socket
import sys
import tempfile
import tracemalloc

from hilrig.wire.transport import RawCanLink, can_frame

MODES = ("rig", "fmu", "engine", "memory", "traced", "tracer-idle", "robot")

WARMUP_CYCLES = 20
ROBOT_START_TIMEOUT_S = 600.0
"""A robot's modules start side by side, each fake node answering from a thread of its own:
under callgrind, which runs one thread at a time, an answer takes far longer than on a bus."""


class AnsweringLink(RawCanLink):
    """A raw-socket link whose peer is a node that answers at once: each exchange first has the
    peer queue the due TPDOs, then runs the C exchange, then drains what the rig sent."""

    def __init__(self, ours: socket.socket, peer: socket.socket, answers: dict[int, bytes]) -> None:
        super().__init__(ours)
        self._peer = peer
        self.answers = answers
        """The frame the node answers with, by COB-ID."""
        self.last_out = b""
        """The frames the last exchange that sent any sent: a cycle's RPDOs, then its SYNC."""
        self.data_bytes = 0
        """Data bytes of every frame either way so far (what the bus carried)."""

    def exchange(self, out, due, decoders, got, timeout_s, cycle=None):  # type: ignore[no-untyped-def]
        if out:
            self.last_out = out
            self.data_bytes += sum(out[offset] for offset in range(4, len(out), 16))  # can_dlc
        for cob_id in due:
            answer = self.answers[cob_id]
            self._peer.send(answer)
            self.data_bytes += answer[4]
        result = super().exchange(out, due, decoders, got, timeout_s, cycle)
        while True:
            try:
                self._peer.recv(16, socket.MSG_DONTWAIT)
            except BlockingIOError:
                return result


def _socket_pair() -> tuple[socket.socket, socket.socket]:
    ours, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    for end in (ours, peer):
        end.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 20)
        end.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    return ours, peer


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=MODES)
    parser.add_argument("cycles", type=int)
    parser.add_argument("--modules", type=int, default=1, help="robot: its modules (node ids 1..N)")
    args = parser.parse_args(argv)
    if args.cycles < 0:
        parser.error("cycles: expected >= 0")
    if args.mode == "robot":
        return robot_probe(args.cycles, args.modules)

    import can

    from hilrig.engine.driver import SYNC_FRAMES
    from hilrig.engine.rig import Rig
    from hilrig.session.fake_node import FakeJointNode
    from hilrig.table import RigTable
    from hilrig.wire.transport import due_table, exchange

    table = RigTable.load()
    channel = "rig-probe"
    folder = tempfile.TemporaryDirectory(prefix="rig-probe-")
    tracer = None
    if args.mode in ("traced", "tracer-idle"):
        from hilrig.observe.tracer import Tracer

        tracer = Tracer.for_scenario(folder.name, table)  # as a HIL session makes it
    with (
        can.Bus(interface="virtual", channel=channel) as rig_bus,
        can.Bus(interface="virtual", channel=channel) as node_bus,
    ):
        fake = FakeJointNode(node_bus, table=table)
        fake.boot()
        ours, peer = _socket_pair()
        attached = tracer if args.mode == "traced" else None
        plant = None
        if args.mode == "fmu":
            from hilrig.plants.fmu import FmuPlant
            from hilrig.resources import JOINT_FMU_MAP

            if not JOINT_FMU_MAP.is_file():
                raise SystemExit(f"rig_probe: no {JOINT_FMU_MAP}: `make build` writes it")
            plant = FmuPlant.load(JOINT_FMU_MAP, table.board, seed=1)
        rig = Rig(rig_bus, table=table, seed=1, tpdo_timeout_s=5.0, tracer=attached, plant=plant)
        answers: dict[int, bytes] = {}
        link = AnsweringLink(ours, peer, answers)
        rig.node.open_link = lambda receive_ids: link  # type: ignore[method-assign]
        try:
            rig.start()  # reads the PDO configuration over SDO, then opens the link
            fake.close()  # from here on the link's peer is the node
            tpdos = [p for p in rig.node.tpdos.values() if p.enabled and p.names]
            answers.update({p.cob_id: can_frame(p.cob_id, bytes(p.length)) for p in tpdos})
            rig.set("velocity_setpoint", 5.0)
            rig.run(cycles=WARMUP_CYCLES)
            gc.collect()
            if args.mode == "engine":
                # The RPDO frames the Rig sent in its last cycle (its exchange's frames but the
                # SYNC), and every cyclic TPDO due at each SYNC.
                out = link.last_out[: -len(SYNC_FRAMES[0])]
                due_by_sync = due_table(tpdos)
                period = len(due_by_sync)
                due = due_by_sync[1:] + due_by_sync[:1]  # due[n % period]: the TPDOs due at SYNC n + 1
                decoders = {p.cob_id: (p.length, p.codec.unpack) for p in tpdos}
                for n in range(args.cycles):
                    got: dict[int, tuple[float | int, ...]] = {}
                    frames = out + SYNC_FRAMES[n % len(SYNC_FRAMES)]
                    while exchange(link, frames, due[n % period], decoders, got, 5.0) is not None:
                        frames = b""
            elif args.mode == "memory":
                # Stopped again: a caller that runs main() in its own process (the tool's
                # test) would otherwise trace every allocation after it, far slower.
                tracemalloc.start()
                try:
                    before, carried = tracemalloc.get_traced_memory()[0], link.data_bytes
                    rig.run(cycles=args.cycles)
                    grown = tracemalloc.get_traced_memory()[0] - before
                finally:
                    tracemalloc.stop()
                cycles, on_bus = max(args.cycles, 1), link.data_bytes - carried
                print(f"{grown / cycles:.1f} bytes kept per cycle, {on_bus / cycles:.1f} on the bus")
            else:
                rig.run(cycles=args.cycles)
                if tracer is not None:
                    tracer.close()  # the rest of the trace sent and written, the file complete
        finally:
            rig.close()
            if tracer is not None:
                tracer.close()
            ours.close()
            peer.close()
            folder.cleanup()
    return 0


def robot_probe(cycles: int, modules: int) -> int:
    """A `Robot` of `modules` modules on the MuJoCo chain, each module's rig over its own
    answering link (its peer a node that answers at once), following the gait for `cycles`
    cycles after the warm-up: the robot engine's own cost per cycle, as `rig` is one Rig's."""
    import can

    from hilrig.apps.gait import TravellingWave
    from hilrig.engine.rig import Rig
    from hilrig.engine.robot import Robot, module_ids
    from hilrig.plants.chain import ChainPhysics
    from hilrig.session.fake_node import FakeJointNode
    from hilrig.table import RigTable

    table = RigTable.load()
    channel = "rig-probe-robot"
    node_ids = module_ids(modules)
    chain = ChainPhysics(modules, seed=1)
    with contextlib.ExitStack() as stack:
        rigs: list[Rig] = []
        fakes = []
        answers: dict[int, bytes] = {}  # every module's: a robot may exchange them all on one link
        for k, node_id in enumerate(node_ids):
            node_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
            fake = FakeJointNode(node_bus, table=table, node_id=node_id)
            fake.boot()
            fakes.append(fake)
            rig_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
            ours, peer = _socket_pair()
            stack.callback(ours.close)
            stack.callback(peer.close)
            link = AnsweringLink(ours, peer, answers)
            rig = Rig(
                rig_bus,
                table=table,
                node_id=node_id,
                plant=chain.models[k],
                sdo_timeout_s=ROBOT_START_TIMEOUT_S,
                boot_timeout_s=ROBOT_START_TIMEOUT_S,
            )
            rig.node.open_link = lambda receive_ids, link=link: link  # type: ignore[method-assign]
            stack.callback(rig.close)
            rigs.append(rig)
        robot = Robot(rigs, chain)
        robot.start()
        TravellingWave().drive(robot)  # its gains over SDO, from the fake nodes
        for fake, rig in zip(fakes, rigs, strict=True):
            fake.close()  # from here on the link's peer is the node
            tpdos = [p for p in rig.node.tpdos.values() if p.enabled and p.names]
            answers.update({p.cob_id: can_frame(p.cob_id, bytes(p.length)) for p in tpdos})
        robot.run(cycles=WARMUP_CYCLES)
        gc.collect()
        robot.run(cycles=cycles)
    return 0


if __name__ == "__main__":
    sys.exit(main())
