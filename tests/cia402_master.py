"""The CiA 402 scenarios' master: python-canopen's `BaseNode402`, unmodified, on its own socket of
the scenario's private bus, and `Stepper`, which keeps the lockstep rig's SYNCs coming while the
master waits on the wall clock.

How a wall-clock master meets a lockstep rig: `BaseNode402` waits on the wall clock (0.4 s per
state change, 0.2 s for a TPDO, 30 s for homing) for the statusword TPDO, which the firmware sends
after each SYNC. While the master runs, `Stepper` runs the rig's lockstep cycles in a thread, so
SYNCs keep coming however long the master takes.

Each next cycle waits until the master's own network has processed the statusword TPDO of the
previous one (a listener on the master's `Network`, after canopen's own, counts them against the
cycles in which the rig saw that TPDO): the master is never more than one cycle behind the bus,
as a master on a real bus is never more than one SYNC period behind its drive. Without it the
rig ran cycles back to back and, on a loaded host, canopen's notifier fell many TPDOs behind:
`BaseNode402.homing()` sends the start bit, waits for ONE statusword TPDO ("one extra cycle") and
then judges the homing bits of the next; both came out of the backlog, sampled before the start
bit reached the drive, so they showed what CiA 402 says for a homing not yet started (bit 10
set, bit 12 clear: "interrupted or not started") and homing() gave up. With the hold, the TPDO
after the one it waits for is sampled at a SYNC sent after the master's controlword, as on a
real bus, and the drive keeps reporting what CiA 402 says.

The verdicts are read from the rig's lockstep history (simulation time, cycle by cycle), never
from how long the master waited: on a loaded host the cycles go by more slowly, the drive and the
master see the same ones. So the master's wall-clock waits are stretched (`stretch_timeouts`):
with the stock 0.2 s for a statusword TPDO, a host busy with a second VM failed the scenario
("Timeout waiting for updated statusword") while the drive answered in the very next cycle. Where
this idealises: a drive that answered many SYNC periods late would still pass the master here; the
cycle it answers in is pinned by the lockstep scenarios (test_pdo_timing.py: a cyclic TPDO in each
SYNC's cycle; test_cia402_fault_reaction.py: the rig as the master, states and duty by cycle).
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import can
import canopen

from boardproto.cia301 import STANDARD_ID_MASK, FunctionCode, NmtCommand, cob_id
from boardproto.cia402 import STATUSWORD_INDEX, State
from boardproto.loader import PROFILE_RANGE
from hilrig.apps.pdo_profile import apply_pdo_profile
from hilrig.engine.observers import RigObserver
from hilrig.pytest_plugin.fixtures import SCENARIO_SDO_TIMEOUT_S

PROFILE = "cia402"
MASTER_RPDOS = (2, 3)  # controlword, mode, target torque; target position, target velocity
HARD_STOP_RAD = -0.1  # gearbox-side angle of the homing scenario's hard stop
WAIT_S = 60.0  # the most a condition of the master's may take on the slowest host
SWITCH_INTERVAL_S = 0.0001
PAUSE_S = 0.001  # between two lockstep cycles: the master's threads run meanwhile
BASE_NODE_402_TIMEOUTS = (
    "TIMEOUT_RESET_FAULT",
    "TIMEOUT_SWITCH_OP_MODE",
    "TIMEOUT_SWITCH_STATE_FINAL",
    "TIMEOUT_SWITCH_STATE_SINGLE",
    "TIMEOUT_CHECK_TPDO",
    "TIMEOUT_HOMING_DEFAULT",
)


class MasterGate(can.Listener):
    """Counts the statusword TPDOs the master's network has processed (added to the network's
    notifier after canopen's own listener, so a frame counts once canopen has handled it)."""

    def __init__(self, cob_id: int) -> None:
        self.cob_id = cob_id
        self.count = 0
        self.condition = threading.Condition()

    def on_message_received(self, msg: can.Message) -> None:
        if msg.arbitration_id == self.cob_id and not msg.is_remote_frame:
            with self.condition:
                self.count += 1
                self.condition.notify_all()


class RigSeen(RigObserver):
    """Counts the cycles in which the rig received the statusword TPDO."""

    def __init__(self, cob_id: int) -> None:
        self.cob_id = cob_id
        self.count = 0

    def on_cycle(self, result) -> None:
        if self.cob_id in result.values_by_cob_id():
            self.count += 1


class Stepper:
    """Runs the rig's lockstep cycles in a thread, each after the master's network processed the
    previous one's statusword TPDO (once `hold_for` gave it the master's gate); `call` runs a
    function between two cycles (the rig is not shared across threads otherwise)."""

    def __init__(self, rig) -> None:
        self.rig = rig
        self._stop = threading.Event()
        self._calls: list[tuple[Callable[[], object], threading.Event]] = []
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._loop, name="lockstep", daemon=True)
        self._gate: MasterGate | None = None
        self._seen = RigSeen(statusword_tpdo(rig).cob_id(rig.node.node_id))
        self.error: BaseException | None = None

    @property
    def statusword_cob_id(self) -> int:
        return self._seen.cob_id

    def hold_for(self, gate: MasterGate | None) -> None:
        """From the next cycle on, wait for `gate` (None: run freely, as before a master)."""
        with self._lock:
            self._gate, self._seen.count = gate, 0

    def _wait_for_master(self) -> None:
        gate, seen = self._gate, self._seen
        if gate is None:
            return
        with gate.condition:
            caught_up = gate.condition.wait_for(
                lambda: gate.count >= seen.count or self._stop.is_set() or self._gate is not gate, WAIT_S
            )
        assert caught_up, f"the master's network processed no statusword TPDO for {WAIT_S} s"

    def _loop(self) -> None:
        try:
            while not self._stop.is_set():
                with self._lock:
                    calls, self._calls = self._calls, []
                for call, done in calls:
                    call()
                    done.set()
                self.rig.run(cycles=1)
                self._wait_for_master()
                # The exchange holds the interpreter while it waits for a cycle's frames: a pause
                # lets the master's threads (canopen's notifier, its SDO client) run between two.
                self._stop.wait(PAUSE_S)
        except BaseException as error:  # reported by stop()
            self.error = error

    def call(self, function: Callable[[], object]) -> None:
        done = threading.Event()
        with self._lock:
            self._calls.append((function, done))
        assert done.wait(WAIT_S), "the lockstep thread stopped"

    def cycles(self, n: int) -> None:
        """Returns once n more cycles ran."""
        end = self.rig.cycle + n
        event = threading.Event()
        while self.rig.cycle < end:
            event.wait(0.005)

    def start(self) -> None:
        # Three threads share the interpreter (the rig's, canopen's notifier, the master's): hand
        # it over in well under a cycle, not after the default 5 ms.
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        self.rig.add_observer(self._seen)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(WAIT_S)
        sys.setswitchinterval(self._switch_interval)
        if self.error is not None:
            raise self.error


NMT_COMMANDS = {
    "OPERATIONAL": NmtCommand.START,
    "STOPPED": NmtCommand.STOP,
    "PRE-OPERATIONAL": NmtCommand.ENTER_PRE_OPERATIONAL,
    "RESET": NmtCommand.RESET_NODE,
    "RESET COMMUNICATION": NmtCommand.RESET_COMMUNICATION,
}
"""python-canopen's `node.nmt.state` words and the NMT command each sends."""


def set_nmt_state(stepper: Stepper, node: canopen.RemoteNode, state: str) -> None:
    """The master's stock `node.nmt.state = state`, sent between two lockstep cycles as a
    master's NMT command goes out between two SYNCs, with the rig told (`Rig.follow_nmt`): from
    the next SYNC on it expects the TPDOs of the state the command leaves the node in. A reset's
    boot-up comes the node's boot time later, counted in those cycles: the master waits for it
    the usual way (`node.nmt.wait_for_bootup()`, which hears only what comes after the call)."""

    def send() -> None:
        node.nmt.state = state
        stepper.rig.follow_nmt(NMT_COMMANDS[state])

    stepper.call(send)


def statusword_tpdo(rig):
    """The profile's TPDO that carries the statusword (0x6041)."""
    profile = rig.table.board.pdo_profile(PROFILE)
    return next(p for p in profile.tpdos if any(e.index == STATUSWORD_INDEX for e in p.entries))


def params_file(folder: Path) -> tuple[str, ...]:
    """The firmware's --params: the profile is stored (0x1010:02), as `hilrig pdo apply` does."""
    return ("--params", str(folder / "params.bin"))


def cia402_face(rig) -> None:
    """The table's "cia402" PDO profile, its master's RPDOs left to the master."""
    rig.node.wait_until_alive(rig.boot_timeout_s)
    apply_pdo_profile(rig.node, rig.table.board.pdo_profile(PROFILE))
    for number in MASTER_RPDOS:
        rig.pause_rpdo(number)


def master_filters(rig) -> list[dict[str, int]]:
    """The master's acceptance filter, as its CAN controller's would be: its node's SDO answers,
    heartbeat and EMCY, and the TPDOs that carry CiA 402 objects. Without it a Python master
    reads every frame of the bus, the rig's sensor frames and SYNCs too, and falls behind."""
    node_id = rig.node.node_id
    profile = rig.table.board.pdo_profile(PROFILE)
    services = (FunctionCode.SDO_RESPONSE, FunctionCode.HEARTBEAT, FunctionCode.SYNC_EMCY)
    ids = [cob_id(function, node_id) for function in services]
    ids += [p.cob_id(node_id) for p in profile.tpdos if any(e.index in PROFILE_RANGE for e in p.entries)]
    return [{"can_id": i, "can_mask": STANDARD_ID_MASK, "extended": False} for i in ids]


@contextmanager
def master(scenario, private_bus, eds) -> Iterator[tuple[canopen.BaseNode402, Stepper]]:
    stepper = Stepper(scenario.rig)
    network = canopen.Network(private_bus.open(can_filters=master_filters(scenario.rig)))
    gate = MasterGate(stepper.statusword_cob_id)
    network.listeners.append(gate)
    # Connected before the first cycle runs: the master's socket gets every statusword TPDO the
    # rig counts (no cycle runs between the scenario's start and here, so none is in flight).
    network.connect()
    stepper.hold_for(gate)
    stepper.start()
    node = canopen.BaseNode402(scenario.rig.node.node_id, str(eds))
    stretch_timeouts(node)
    network.add_node(node)
    try:
        node.nmt.wait_for_heartbeat(WAIT_S)
        yield node, stepper
    finally:
        stepper.hold_for(None)
        with gate.condition:
            gate.condition.notify_all()
        network.disconnect()
        stepper.stop()


def stretch_timeouts(node: canopen.BaseNode402) -> None:
    """BaseNode402 as it ships, its wall-clock waits longer: its SDO client waits as long as the
    rig's own (the scenarios' SDO timeout), not canopen's 0.3 s, and each of its own timeouts by
    the same factor (0.2 s for a TPDO becomes over 3 s): a loaded host answers late, never wrongly."""
    factor = SCENARIO_SDO_TIMEOUT_S / canopen.sdo.SdoClient.RESPONSE_TIMEOUT
    node.sdo.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
    for name in BASE_NODE_402_TIMEOUTS:
        setattr(node, name, getattr(canopen.BaseNode402, name) * factor)


def wait_for(condition: Callable[[], bool], what: str) -> None:
    event = threading.Event()
    for _ in range(int(WAIT_S / 0.01)):
        if condition():
            return
        event.wait(0.01)
    raise AssertionError(f"the drive never got there: {what}")


def states_seen(rig) -> list[str]:
    """The drive's states in the order the statusword TPDO showed them, each run once."""
    _, words = rig.history("statusword")
    names: list[str] = []
    for word in words:
        state = next((s.text for s in State if int(word) & s.mask == s.value), "?")
        if not names or names[-1] != state:
            names.append(state)
    return names


class HardStop:
    """A hard stop on the joint (an observer of the rig's cycles): at HARD_STOP_RAD the motor
    is held as by a mechanical stop while the drive pushes into it, free as soon as it pulls
    away."""

    def __init__(self, rig) -> None:
        self.plant = rig.plant
        self.gear_ratio = self.plant.params.gear_ratio

    def on_cycle(self, result) -> None:
        state = self.plant.state
        at_stop = state.motor_angle_rad / self.gear_ratio <= HARD_STOP_RAD and state.applied_duty <= 0.0
        self.plant.set_motor_held(at_stop)

    def __getattr__(self, name: str) -> Callable[..., None]:
        return lambda *args, **kwargs: None  # every other observer callback: nothing to do
