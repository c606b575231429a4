"""A modular robot on one bus: N joint modules (the same firmware started N times, node ids 1..N
or a list), one SYNC per cycle for all, the chain's mechanics from MuJoCo
(`hilrig.plants.chain`), on the one lockstep engine (`hilrig.engine.lockstep`)::

    with hil_session(RunDescription(TraceRun(Path("out/robot")), robot=RobotRun(8))) as session:
        robot = session.robot
        robot.set_all("control_mode", ControlMode.POSITION)
        robot.before_each_cycle(lambda r: r.set_each("position_setpoint", gait(r.t)))
        robot.run(seconds=2.0)
        t, angle = robot.module(3).history("output_position")

Each module is a `Rig` of its own (its node, its SDO, its history and trace under
/modules/<id>), whose driver the robot steps: every module's RPDOs, then one SYNC, then every
module's due TPDOs, then one physics step of the whole chain with the outputs each module
applied to its plant.

The rig is the bus master: it also sends the master's heartbeat (every `MasterHeartbeat.period_ms`
of simulation time) and configures each module's heartbeat consumer (CiA 301 0x1016) to watch it,
so a module whose master falls silent goes to its safe state on its own.

A robot may carry other boards on the same bus (*riders*: the head module on the snake, its own
firmware, table and plant): they come after the joints in `modules`, take part in the same
exchange of every cycle, and their plants step on their own beside the chain. `set_all` and
`set_each` set a field on the modules whose board has it.

A module whose firmware dies (killed, crashed) is *lost*: the cycle its TPDOs were due in names it
(`Robot.lost`, an event on the trace), its motor bridge is off from then on (duty 0: the joint is
limp, its link still moves with the chain), and the other modules run on as before: a module does
not depend on its neighbours, only on the master, which decides what the robot does next.
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from boardproto.cia301 import (
    HEARTBEAT_CONSUMER_INDEX,
    MASTER_HEARTBEAT_MS,
    MASTER_NODE_ID,
    MAX_NODE_ID_WITH_PDO_5_TO_8,
    MIN_NODE_ID,
    NmtState,
    heartbeat_cob_id,
    heartbeat_consumer_entry,
)
from hilrig.engine.driver import (
    BUS_EVENTS_PATH,
    LIVENESS_SLICE_S,
    SYNC_FRAMES,
    CycleResult,
    Value,
    sync_counter,
)
from hilrig.engine.lockstep import CycleStart, HangGuard, LockstepDriver
from hilrig.engine.rig import Rig
from hilrig.engine.timeline import CycleRunner
from hilrig.errors import FirmwareError, LockstepError
from hilrig.plants.interface import Plant
from hilrig.wire.transport import Decoder, Exchange, FrameLink, can_frame, exchanger, send_frames

if TYPE_CHECKING:
    from hilrig.plants.chain import ChainGeometry

ROBOT_EVENTS_PATH = "/events/robot"
"""Where the robot's own events (a module lost, the master heartbeat stopped) go on the trace."""


@dataclass(frozen=True)
class ModuleProcess(Protocol):
    """What the robot needs of a module's firmware process (a `hilrig.session.firmware.Firmware`)."""

    def kill(self) -> None: ...


class MasterHeartbeat:
    """The master's heartbeat the rig produces, and what each module's consumer is told.

    node_id: the master's (the rig's) node id on the bus; period_ms: how often it sends its
    heartbeat, in simulation time; consumer_ms: how long a module waits for the next one before
    it declares the master lost (CiA 301 wants it above the producer period: here 2.5 periods,
    so one lost frame is not a lost master)."""

    node_id: int = MASTER_NODE_ID
    period_ms: int = MASTER_HEARTBEAT_MS
    consumer_ms: int = 5 * MASTER_HEARTBEAT_MS // 2

    def __post_init__(self) -> None:
        heartbeat_consumer_entry(self.node_id, self.consumer_ms)  # the same range checks
        if not 0 < self.period_ms < self.consumer_ms:
            raise ValueError(
                f"master heartbeat: period {self.period_ms} ms must be above 0 and below the "
                f"consumer time {self.consumer_ms} ms"
            )


@dataclass(frozen=True)
class LostModule:
    """A module whose firmware stopped answering because its process is gone."""

    node_id: int
    cycle: int
    t: float
    reason: str

    def __str__(self) -> str:
        return (
            f"module node 0x{self.node_id:02X} lost at cycle {self.cycle} (t = {self.t:.6g} s): {self.reason}"
        )


class ChainModel(Protocol):
    """The mechanics a robot steps (`hilrig.plants.chain.ChainPhysics`): one coupled plant per
    module (`models`, each a module rig's `Plant`), stepped together by one control period with
    the outputs each module's cycle applied to its plant."""

    @property
    def models(self) -> Sequence[Plant]: ...

    def step(self, dt_s: float) -> None: ...

    @property
    def link_count(self) -> int:
        """Links: one more than the joints (the head)."""
        ...

    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Every link's frame: positions (links x 3) [m], quaternions w x y z (links x 4); the
        link's capsule runs back along the frame's -x axis."""
        ...

    @property
    def geometry(self) -> ChainGeometry: ...


class RobotObserver:
    """Watches a robot's cycles (after its modules' observers) and its own events."""

    def on_robot_cycle(self, robot: Robot, cycle: int, t: float) -> None:
        """One completed cycle of the whole robot (the chain has been stepped)."""

    def on_robot_event(self, text: str, *, warning: bool, cycle: int, t: float) -> None:
        """A module lost, the master heartbeat stopped or resumed."""


def module_ids(modules: int | Sequence[int]) -> tuple[int, ...]:
    """Node ids of a robot's modules: N -> 1..N, or the given list. ValueError naming the id when
    one is given twice (two modules answering one id would corrupt every SDO and PDO of it) or
    out of 1..63 (PDO 5..8 of node N use the identifiers of node N + 64)."""
    ids = tuple(range(1, modules + 1)) if isinstance(modules, int) else tuple(modules)
    if not ids:
        raise ValueError("a robot needs at least one module")
    seen: set[int] = set()
    for node_id in ids:
        if not MIN_NODE_ID <= node_id <= MAX_NODE_ID_WITH_PDO_5_TO_8:
            raise ValueError(
                f"module node id {node_id}: expected {MIN_NODE_ID}..{MAX_NODE_ID_WITH_PDO_5_TO_8} "
                "(PDO 5..8 of node N use the identifiers of node N + 64)"
            )
        if node_id in seen:
            raise ValueError(
                f"node id {node_id} (0x{node_id:02X}) is given to two modules: each module on "
                "the bus needs its own"
            )
        seen.add(node_id)
    return ids


class Robot(CycleRunner):
    """N modules (one `Rig` each, lockstep) and the chain's mechanics, stepped as one.

    modules: the modules' rigs, in chain order (joint k of `chain` is module k); each must be
    constructed with `plant=chain.models[k]`. Any modules after the chain's joints are riders:
    other boards with plants of their own, stepped by the robot after the chain. firmware: each
    module's process (None for a board the robot did not start), so `kill()` can end one and a
    lost one is named with its exit.
    master: the heartbeat the rig produces and the modules watch (None: no heartbeat at all).
    """

    def __init__(
        self,
        modules: Sequence[Rig],
        chain: ChainModel,
        *,
        firmware: Sequence[ModuleProcess | None] = (),
        master: MasterHeartbeat | None = None,
    ) -> None:
        if not modules:
            raise ValueError("a robot needs at least one module")
        module_ids([m.node.node_id for m in modules])
        joints = len(chain.models)
        if joints > len(modules):
            raise ValueError(f"chain has {joints} joints for {len(modules)} modules")
        periods = {m.driver.period_us for m in modules}
        if len(periods) != 1:
            raise ValueError(f"modules with different periods: {sorted(periods)} us")
        self._period_us = periods.pop()
        self.modules: tuple[Rig, ...] = tuple(modules)
        self._drivers: list[LockstepDriver] = []
        for k, module in enumerate(self.modules):
            if not isinstance(module.driver, LockstepDriver):
                raise ValueError(f"node 0x{module.node.node_id:02X}: a robot runs its modules in lockstep")
            if k < joints and module.plant is not chain.models[k]:
                raise ValueError(f"node 0x{module.node.node_id:02X}: its plant is not joint {k} of the chain")
            module.robot = self
            self._drivers.append(module.driver)
        self.chain = chain
        self.joints: tuple[Rig, ...] = self.modules[:joints]
        """The chain's modules, joint k first."""
        self.riders: tuple[Rig, ...] = self.modules[joints:]
        """Other boards on the robot's bus, each with a plant of its own (the head module)."""
        self.firmware: tuple[ModuleProcess | None, ...] = tuple(firmware) or (None,) * len(modules)
        if len(self.firmware) != len(modules):
            raise ValueError(f"{len(self.firmware)} firmware processes for {len(modules)} modules")
        self.master = master
        self.master_heartbeat_on = master is not None
        """Whether the rig sends the master heartbeat (`stop_master_heartbeat`)."""
        self._heartbeat_every = 0
        self._heartbeat_frame = b""
        if master is not None:
            every, rest = divmod(master.period_ms * 1000, self._period_us)
            if rest or every < 1:
                raise ValueError(
                    f"master heartbeat period {master.period_ms} ms is not a whole number of "
                    f"{self._period_us} us cycles"
                )
            self._heartbeat_every = every
            self._heartbeat_frame = can_frame(heartbeat_cob_id(master.node_id), bytes([NmtState.OPERATIONAL]))
        self.lost: dict[int, LostModule] = {}
        """Modules lost so far, by node id."""
        self.observers: list[RobotObserver] = []
        self._cycle = 0
        self._live: list[int] = list(range(len(self.modules)))  # indexes of modules not lost
        self._link: FrameLink | None = None  # every module's, from the first cycle (`_share_link`)
        self._exchange_call: Exchange | None = None
        self._owners: dict[int, list[int]] = {}  # COB-ID -> the modules (indexes) receiving it
        self._decoders: dict[int, Decoder] = {}  # every module's TPDOs'
        self._tpdo_ids: list[tuple[int, ...]] = []  # each module's TPDO COB-IDs, by index
        self._shared_by: list[LockstepDriver] = []  # the drivers sharing the link, as shared
        self._polled_tpdos = False  # `poll` handed a module a TPDO, which its next cycle takes
        self._carriers_of: dict[str, dict[int, int]] = {}  # field name -> `_carriers`
        self._init_timeline()

    # --- Life cycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Bring every module up (`Rig.start`), with its heartbeat consumer watching the master.
        The modules start side by side (each has its own bus handle and SDO client): bringing one
        up is some eighty SDO round trips (identity, the whole PDO configuration), latency more
        than work, so eight in a row would take eight times as long for nothing."""
        workers = len(self.modules)
        with concurrent.futures.ThreadPoolExecutor(workers, thread_name_prefix="module-start") as pool:
            for future in [pool.submit(self._start_module, module) for module in self.modules]:
                future.result()  # the first failure (in module order) is raised

    def _start_module(self, module: Rig) -> None:
        module.node.wait_until_alive(module.boot_timeout_s, liveness=module.liveness)
        if self.master is not None:
            entry = heartbeat_consumer_entry(self.master.node_id, self.master.consumer_ms)
            module.node.download(HEARTBEAT_CONSUMER_INDEX, 1, entry.to_bytes(4, "little"))
        module.start()

    def close(self) -> None:
        for module in self.modules:
            module.close()

    # --- The modules ----------------------------------------------------------------------
    @property
    def node_ids(self) -> tuple[int, ...]:
        return tuple(m.node.node_id for m in self.modules)

    def module(self, node_id: int) -> Rig:
        """The module with this node id."""
        for module in self.modules:
            if module.node.node_id == node_id:
                return module
        raise KeyError(f"no module with node id {node_id}; the robot has {list(self.node_ids)}")

    def _carriers(self, name: str) -> dict[int, int]:
        """The modules whose board has the field `name`: module index -> its place among them
        (every module when none has it: their `Rig.set` then names the typo)."""
        carriers = self._carriers_of.get(name)
        if carriers is None:
            having = [k for k, module in enumerate(self.modules) if name in module.table.names]
            carriers = {k: j for j, k in enumerate(having or range(len(self.modules)))}
            self._carriers_of[name] = carriers
        return carriers

    def set_all(self, name: str, value: float) -> None:
        """`Rig.set(name, value)` on every module not lost whose board has the field."""
        carriers = self._carriers(name)
        for k in self._live:
            if k in carriers:
                self.modules[k].set(name, value)

    def set_each(self, name: str, values: Sequence[float]) -> None:
        """`Rig.set(name, values[j])` on the j-th module (in chain order) whose board has the
        field (every joint, not a rider without it), lost modules skipped. Every cycle for a
        gait: a field an RPDO carries goes straight into each module's next frame."""
        carriers = self._carriers(name)
        if len(values) != len(carriers):
            raise ValueError(f"{name}: {len(values)} values for {len(carriers)} modules")
        live = [k for k in self._live if k in carriers]
        drivers = self._drivers
        if all(drivers[k].rpdo_of(name) is not None for k in live):
            for k in live:
                drivers[k].set_rpdo_value(name, values[carriers[k]])
            return
        for k in live:
            self.modules[k].set(name, values[carriers[k]])

    def kill(self, node_id: int) -> None:
        """SIGKILL one module's firmware now, as a crash or a pulled plug would end it; the next
        cycle finds it lost."""
        k = self.node_ids.index(node_id) if node_id in self.node_ids else None
        firmware = self.firmware[k] if k is not None else None
        if firmware is None:
            raise KeyError(f"node id {node_id}: no firmware process of this robot to kill")
        firmware.kill()

    def stop_master_heartbeat(self) -> None:
        """Stop sending the master's heartbeat (SYNC and PDOs go on): the modules' consumers
        must notice within their consumer time."""
        self._set_master_heartbeat(False)

    def resume_master_heartbeat(self) -> None:
        self._set_master_heartbeat(True)

    def _set_master_heartbeat(self, on: bool) -> None:
        if self.master is None:
            raise RuntimeError("this robot has no master heartbeat (master=None)")
        if on != self.master_heartbeat_on:
            self.master_heartbeat_on = on
            what = "resumed" if on else "stopped"
            self._event(f"master heartbeat (node 0x{self.master.node_id:02X}) {what}", warning=not on)

    # --- Time -------------------------------------------------------------------------------
    @property
    def cycle(self) -> int:
        return self._cycle

    @property
    def t(self) -> float:
        return self._cycle * self._period_us / 1e6

    @property
    def period_us(self) -> int:
        return self._period_us

    @property
    def period_s(self) -> float:
        return self._period_us / 1e6

    def _step(self) -> None:
        n = self._cycle
        drivers = self._drivers
        if self._link is None or not all([driver.shares_link for driver in self._shared_by]):
            self._share_link()  # first cycle, or a module configured again since (its own link)
        # Every module's RPDOs, the master's heartbeat when due and one SYNC go out together, at
        # the start of the one exchange that takes every module's due TPDOs in (`_exchange`).
        starts = {k: drivers[k].begin_cycle(send=False) for k in self._live}
        out = b"".join([start.unsent for start in starts.values()])
        if self.master_heartbeat_on and n % self._heartbeat_every == 0:
            out += self._heartbeat_frame
        got = self._exchange(n, starts, out + SYNC_FRAMES[sync_counter(n) - 1])
        results: list[CycleResult | None] = [None] * len(drivers)
        for k, start in starts.items():  # the modules lost in this cycle are no longer in `starts`
            results[k] = drivers[k].end_cycle(start, got[k])
        for k, driver in enumerate(drivers):
            if results[k] is None:  # lost: its hardware gets no outputs, and still has a truth
                driver.plant.apply(None)
                state = driver.plant.truth()
                driver.history.record_truth(state)
                t = driver.history.time_of(n)
                results[k] = CycleResult(n, t, sync_counter(n), None, (), None, (), state)
        self.chain.step(self.period_s)
        for k in range(len(self.joints), len(drivers)):  # the riders' own hardware
            drivers[k].plant.step(self.period_s)
        self._cycle = n + 1
        for k, driver in enumerate(drivers):
            driver.cycle = n + 1
            result = results[k]
            assert result is not None
            self.modules[k].after_cycle(result)
        for observer in self.observers:
            observer.on_robot_cycle(self, n, n * self._period_us / 1e6)

    # --- The shared link --------------------------------------------------------------------
    def _share_link(self) -> None:
        """One link for every module's per-cycle frames (on SocketCAN one raw socket with the
        kernel filters of all of them): the modules' drivers send on it and poll through the
        robot (`poll`), and a cycle's RPDOs, SYNC and due TPDOs of all modules are one exchange
        (`transport.exchange`, one call into C on a raw socket), not one per module."""
        drivers = self._drivers
        owners: dict[int, list[int]] = {}
        for k, driver in enumerate(drivers):
            for cob_id in driver.receive_ids():
                owners.setdefault(cob_id, []).append(k)
        link = self.modules[0].node.open_link(list(owners))
        exchange = exchanger(link)
        for driver in drivers:
            driver.share_link(link, exchange, self.poll)
        self._link, self._exchange_call, self._owners = link, exchange, owners
        self._tpdo_ids = [tuple(driver.tpdo_cob_ids) for driver in drivers]
        self._shared_by = [drivers[k] for k in self._live]
        self._polled_tpdos = True  # what the drivers polled on their own links, for the next cycle
        self._decoders = {
            cob_id: decoder for driver in drivers for cob_id, decoder in driver.decoders.items()
        }

    def poll(self, timeout_s: float = 0.0) -> None:
        """Take in what arrived on the shared link since the last cycle, each frame handed to
        the module(s) whose COB-ID it is (`Driver.accept_polled`): what every module's
        `Driver.poll` does while the link is shared."""
        link = self._link
        if link is None:
            return
        drivers, owners = self._drivers, self._owners
        frame = link.recv(timeout_s)
        while frame is not None:
            for k in owners.get(frame[0], ()):
                drivers[k].accept_polled(*frame)
                self._polled_tpdos = True  # (or an EMCY, dispatched already: a look for nothing)
            frame = link.recv(0.0)

    def _exchange(
        self, n: int, starts: dict[int, CycleStart], out: bytes
    ) -> dict[int, dict[int, tuple[Value, ...]]]:
        """Send `out` (every module's RPDOs, the SYNC), then take every module's TPDOs due at
        this SYNC in one exchange (the wall-clock bound is only each module's hang guard), each
        other frame judged by the module whose COB-ID it is (`LockstepDriver.take`, as a
        module's own cycle judges it). A module whose process died is lost (`_lose`, out of
        `starts`); a TPDO late, missing or malformed of a live one is its LockstepError. Returns
        each module's TPDO values by COB-ID, each also in its history's rows."""
        drivers, owners = self._drivers, self._owners
        due = frozenset().union(*[start.due for start in starts.values()])
        got: dict[int, tuple[Value, ...]] = {}
        guards: dict[int, HangGuard] = {}
        k = -1  # the module a LockstepError is of
        try:
            if self._polled_tpdos:
                self._polled_tpdos = False
                for k, start in starts.items():
                    pending = drivers[k].take_pending()
                    if pending and out:
                        send_frames(self._link, out)  # the SYNC is on the bus, as when nothing was pending
                        out = b""
                    for cob_id, data in pending:  # polled between cycles: late or duplicate, unless acyclic
                        drivers[k].take(got, start, cob_id, data, between_syncs=True)
            while True:
                frame = self._exchange_call(out, due, self._decoders, got, LIVENESS_SLICE_S, n)
                if frame is None:
                    break
                out = b""
                if frame is not False:
                    for k in owners.get(frame[0], ()):  # type: ignore[index]
                        start = starts.get(k)
                        if start is None:
                            continue  # a module lost in this cycle
                        driver = drivers[k]
                        driver.take(got, start, *frame)  # type: ignore[misc]
                        if start.due and not driver.operational:  # it left operational (a heartbeat event)
                            due = due - start.due.difference(got)
                    continue
                for k, start in list(starts.items()):  # a quiet slice: whose TPDOs are missing?
                    if start.due.issubset(got):
                        continue
                    driver = drivers[k]
                    guard = guards.get(k)
                    if guard is None:
                        guard = HangGuard(driver.tpdo_timeout_s, driver.activity, LIVENESS_SLICE_S)
                        guards[k] = guard
                    try:
                        given_up = driver.check_alive(start, got, guard)
                    except FirmwareError as error:
                        del starts[k]
                        driver.forget_rows(n, got)
                        for cob_id in self._tpdo_ids[k]:
                            got.pop(cob_id, None)
                        due = due - start.due
                        self._lose(k, start, error)
                        continue
                    if given_up:  # `on_problem` has it: the cycle ends without them
                        due = due - start.due.difference(got)
        except LockstepError as error:  # alive, but a TPDO late, missing or malformed
            if k >= 0:
                self.modules[k].log_event(BUS_EVENTS_PATH, str(error))
            for k in starts:
                drivers[k].forget_rows(n, got)
            raise
        except BaseException:
            for k in starts:
                drivers[k].forget_rows(n, got)
            raise
        if len(starts) == 1:
            return dict.fromkeys(starts, got)  # one module's: all of it
        tpdo_ids = self._tpdo_ids
        return {k: {cob_id: got[cob_id] for cob_id in tpdo_ids[k] if cob_id in got} for k in starts}

    def _lose(self, k: int, start: CycleStart, error: FirmwareError) -> None:
        module = self.modules[k]
        reason = str(error).split("\n", 1)[0]
        reason = reason.split(": ", 1)[1] if reason.startswith("cycle ") else reason
        lost = LostModule(module.node.node_id, start.cycle, start.t, reason)
        self.lost[lost.node_id] = lost
        self._live.remove(k)
        if not self._live:
            raise FirmwareError(f"every module of the robot is lost; the last: {lost}") from error
        self._event(str(lost), warning=True, cycle=start.cycle, t=start.t)
        module.log_event("/events/lost", str(lost))

    def _event(self, text: str, *, warning: bool, cycle: int | None = None, t: float | None = None) -> None:
        cycle = self._cycle if cycle is None else cycle
        t = self.t if t is None else t
        for observer in self.observers:
            observer.on_robot_event(text, warning=warning, cycle=cycle, t=t)

    def add_observer(self, observer: RobotObserver) -> None:
        self.observers.append(observer)

    # --- Values of all modules --------------------------------------------------------------
    def histories(self, name: str) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """`Rig.history(name)` of every module, by node id."""
        return {m.node.node_id: m.history(name) for m in self.modules}

    def truths(self, name: str) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """`Rig.truth(name)` of every module, by node id."""
        return {m.node.node_id: m.truth(name) for m in self.modules}


__all__ = [
    "ROBOT_EVENTS_PATH",
    "ChainModel",
    "LostModule",
    "MasterHeartbeat",
    "Robot",
    "RobotObserver",
    "module_ids",
]
