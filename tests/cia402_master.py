"""The CiA 402 scenarios' master: python-canopen's `BaseNode402`, unmodified and with its stock
timeouts, on its own socket of the scenario's private bus, and `Stepper`, which keeps the
lockstep rig's SYNCs coming while the master waits on the wall clock.

How a wall-clock master meets a lockstep rig: `BaseNode402` waits on the wall clock (0.4 s per
state change, 0.2 s for a TPDO, 30 s for homing) for the statusword TPDO, which the firmware sends
after each SYNC. While the master runs, `Stepper` runs the rig's lockstep cycles back to back in
a thread, so SYNCs keep coming however long the master takes; a command of the master takes
effect at the next SYNC, one cycle later, far inside every timeout at any host load. The verdicts
are read from the rig's lockstep history (simulation time, cycle by cycle), never from how long
the master waited: on a loaded host the master sees more cycles go by, the drive the same.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import canopen

from boardproto.cia301 import STANDARD_ID_MASK, FunctionCode, cob_id
from boardproto.cia402 import State
from boardproto.loader import PROFILE_RANGE
from hilrig.apps.pdo_profile import apply_pdo_profile
from hilrig.pytest_plugin.fixtures import SCENARIO_SDO_TIMEOUT_S

PROFILE = "cia402"
MASTER_RPDOS = (2, 3)  # controlword, mode, target torque; target position, target velocity
HARD_STOP_RAD = -0.1  # gearbox-side angle of the homing scenario's hard stop
WAIT_S = 60.0  # the most a condition of the master's may take on the slowest host
SWITCH_INTERVAL_S = 0.0001
PAUSE_S = 0.001  # between two lockstep cycles: the master's threads run meanwhile


class Stepper:
    """Runs the rig's lockstep cycles back to back in a thread; `call` runs a function between
    two cycles (the rig is not shared across threads otherwise)."""

    def __init__(self, rig) -> None:
        self.rig = rig
        self._stop = threading.Event()
        self._calls: list[tuple[Callable[[], object], threading.Event]] = []
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._loop, name="lockstep", daemon=True)
        self.error: BaseException | None = None

    def _loop(self) -> None:
        try:
            while not self._stop.is_set():
                with self._lock:
                    calls, self._calls = self._calls, []
                for call, done in calls:
                    call()
                    done.set()
                self.rig.run(cycles=1)
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
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(WAIT_S)
        sys.setswitchinterval(self._switch_interval)
        if self.error is not None:
            raise self.error


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
    stepper.start()
    network = canopen.Network(private_bus.open(can_filters=master_filters(scenario.rig)))
    network.connect()
    node = canopen.BaseNode402(scenario.rig.node.node_id, str(eds))
    # BaseNode402 as it ships; its SDO client waits as long as the rig's own (the scenarios'
    # SDO timeout), not canopen's 0.3 s: a loaded host answers late, never wrongly.
    node.sdo.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
    network.add_node(node)
    try:
        node.nmt.wait_for_heartbeat(WAIT_S)
        yield node, stepper
    finally:
        network.disconnect()
        stepper.stop()


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
