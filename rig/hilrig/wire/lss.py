"""The LSS master (CiA 305): find nodes without a node id, give each one, store it, and number a
modular robot's modules in chain order. Built on python-canopen's `LssMaster` (`network.lss`):
its configure, store, inquire and switch services are used as they are; only fastscan is our
own, because canopen's `fast_scan()` scans all 128 bits with fixed sleeps (and a 0.5 s timeout
for every 1 bit), where a master that knows the board's vendor, product and revision (the EDS
does) confirms those three parts with one frame each and scans the 32 bits of the serial alone.

    network = canopen.Network(bus); network.connect()
    lss = LssCommissioner(network, timeout_s=0.2)
    address = lss.fastscan(known=LssAddress.of_product(vendor, product, revision))
    lss.assign(5, store=True)                 # the node found is in configuration: id 5, stored
    lss.wait_for_boot_up(5, timeout_s=2)      # it takes it at once (it had none) and boots

Chain order (`number_chain`). Fastscan finds nodes in the order of their identity, not of their
place in the robot. The firmware design gives each module a chain enable input and output
(`firmware/canopen/LssSlave.hpp`): a module takes part in LSS only while its input is high, and
raises its output (its downstream neighbour's input) once it has a node id. Module 1's input is
the master's (always high). So at any moment exactly one module without an id is enabled, the
next one in the chain, and "fastscan, assign k, wait for its boot-up" numbers the chain 1..n in
order. Why an enable line rather than switching each module's downstream neighbour's power: it
is one signal wire per joint rather than a switch carrying every downstream motor's current, a
module that resets does not power-cycle the rest of the robot, and every module is up (and
flashable, its serial readable) before it has an id. The rig emulates the wire with one file per
link (`hilrig.session.chain`).

Absence of an answer is how LSS says "no": each question waits `timeout_s` at most (wall time,
the protocol's own), and an answer that comes later is dropped before the next question.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Self

import can
import canopen
from canopen.lss import LssError as CanopenLssError

from boardproto.cia301 import NmtState, heartbeat_cob_id, is_node_id
from boardproto.cia305 import (
    FASTSCAN_CONFIRM,
    FASTSCAN_HIGHEST_BIT,
    IDENTITY_PARTS,
    MASTER_COB_ID,
    LssCommand,
    LssState,
    command_frame,
    fastscan_frame,
)
from hilrig.errors import NodeSilentError, RigError

DEFAULT_TIMEOUT_S = 0.2
"""How long an LSS question waits for an answer; silence is the answer "no"."""
SCAN_ATTEMPTS = 3
"""How many times fastscan scans one part before it gives up (a late answer spoils a scan)."""
CHAIN_SETTLE_ASKS = 3
"""In chain order, how many times the master asks again for a module without an id after the
last one booted: the next module sees its enable input rise a little after that boot-up."""


class LssFailure(RigError):
    """An LSS service was refused or lost track (the error names which and why)."""


@dataclass(frozen=True)
class LssAddress:
    """The LSS address: 0x1018 sub 1..4. `None` in a part: not known (fastscan finds it)."""

    vendor_id: int | None
    product_code: int | None
    revision: int | None
    serial_number: int | None

    @classmethod
    def of_product(cls, vendor_id: int, product_code: int, revision: int) -> LssAddress:
        return cls(vendor_id, product_code, revision, None)

    def parts(self) -> tuple[int | None, ...]:
        return (self.vendor_id, self.product_code, self.revision, self.serial_number)

    def __str__(self) -> str:
        return " ".join(
            f"{name} {'?' if value is None else f'0x{value:08X}'}"
            for name, value in zip(("vendor", "product", "revision", "serial"), self.parts(), strict=True)
        )


UNKNOWN = LssAddress(None, None, None, None)


class LssCommissioner:
    """The rig's LSS master on a canopen Network (connected: its receive thread delivers the
    answers to `network.lss`). It owns nothing: the network stays the caller's."""

    def __init__(self, network: canopen.Network, *, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        self.network = network
        self.master = network.lss
        self.master.RESPONSE_TIMEOUT = timeout_s
        self.timeout_s = timeout_s
        self.questions = 0
        """LSS requests sent that wait for an answer (fastscan steps included)."""

    # --- fastscan ------------------------------------------------------------------------
    def _ask(self, data: bytes) -> bytes | None:
        """Send one request and return the answer, None after `timeout_s` of silence. Answers
        left from an earlier question (a late one) are dropped first."""
        responses = self.master.responses
        while True:
            try:
                responses.get_nowait()
            except queue.Empty:
                break
        self.questions += 1
        self.network.send_message(MASTER_COB_ID, data)
        try:
            return bytes(responses.get(timeout=self.timeout_s))
        except queue.Empty:
            return None

    def read_identity(self, node_id: int, timeout_s: float) -> LssAddress:
        """Node `node_id`'s 0x1018 over SDO (`read_identity`): the verification after LSS."""
        return read_identity(self.network, node_id, timeout_s)

    def _identified(self, data: bytes) -> bool:
        answer = self._ask(data)
        return answer is not None and answer[0] == LssCommand.IDENTIFY_SLAVE

    def any_unconfigured(self) -> bool:
        """True when some node without a node id takes part in LSS (fastscan's reset step: every
        such node answers it, and starts its scan afresh)."""
        return self._identified(fastscan_frame(0, FASTSCAN_CONFIRM, 0, 0))

    def fastscan(self, known: LssAddress = UNKNOWN) -> LssAddress | None:
        """The LSS address of the node without a node id that has the lowest one (among those
        matching the `known` parts), now in the configuration state; None when no such node
        answers. Known parts cost one frame each, an unknown part 33 (one per bit, a silent one
        for each 1 bit, then the confirmation)."""
        if not self.any_unconfigured():
            return None
        found: list[int] = []
        for sub, part in enumerate(known.parts()):
            next_sub = (sub + 1) % IDENTITY_PARTS
            if part is not None:
                if not self._identified(fastscan_frame(part, 0, sub, next_sub)):
                    return None  # no node without an id has this part
                found.append(part)
                continue
            found.append(self._scan_confirmed(sub, next_sub))
        return LssAddress(*found)

    def _scan_confirmed(self, sub: int, next_sub: int) -> int:
        """One unknown part, scanned bit by bit and confirmed. An answer later than timeout_s
        reads as a 1 and the confirmation then fails; the nodes still wait at this part, so it
        is scanned again (SCAN_ATTEMPTS in all)."""
        for _ in range(SCAN_ATTEMPTS):
            value = self._scan_part(sub)
            if self._identified(fastscan_frame(value, 0, sub, next_sub)):
                return value
        raise LssFailure(
            f"fastscan lost track at part {sub} (0x{value:08X}) {SCAN_ATTEMPTS} times: answers came later "
            f"than {self.timeout_s:g} s, or the node left the scan; --timeout S waits longer"
        )

    def _scan_part(self, sub: int) -> int:
        value = 0
        for position in range(FASTSCAN_HIGHEST_BIT, -1, -1):  # protocol-literal: bit 31 down to 0
            if not self._identified(fastscan_frame(value, position, sub, sub)):
                value |= 1 << position  # nobody left has a 0 there
        return value

    def identify_non_configured(self) -> bool:
        """True when a node without a node id answers CiA 305's identify non-configured
        remote slave."""
        answer = self._ask(command_frame(LssCommand.IDENTIFY_NON_CONFIGURED_REMOTE))
        return answer is not None and answer[0] == LssCommand.IDENTIFY_NON_CONFIGURED_SLAVE

    # --- configuration (canopen's LssMaster) ----------------------------------------------
    def select(self, address: LssAddress) -> None:
        """Switch state selective: the node with this whole address into configuration."""
        parts = address.parts()
        if any(part is None for part in parts):
            raise ValueError(f"switch state selective needs the whole address, got {address}")
        if not self.master.send_switch_state_selective(*parts):
            raise NodeSilentError(f"no node with LSS address {address} answered switch state selective")

    def assign(self, node_id: int, *, store: bool = True) -> None:
        """Give the node(s) in configuration `node_id`, store it if `store`, and switch back to
        waiting: a node that had no id takes it at once (reset communication, boot-up), one that
        had an id takes it at its next reset communication."""
        if not is_node_id(node_id):
            raise ValueError(f"node id: expected 1..127, got {node_id}")
        try:
            self.master.configure_node_id(node_id)
            if store:
                self.master.store_configuration()
        except CanopenLssError as error:
            raise LssFailure(f"LSS refused node id 0x{node_id:02X}: {error}") from None
        finally:
            self.master.send_switch_state_global(LssState.WAITING)

    def inquire_node_id(self) -> int:
        """The active node id of the node in configuration (0xFF: none)."""
        return int(self.master.inquire_node_id())

    # --- boot-up ---------------------------------------------------------------------------
    def boot_up_watch(self, node_id: int) -> BootUpWatch:
        """Subscribe before the request that makes `node_id` boot, so no boot-up is missed."""
        return BootUpWatch(self.network, node_id)

    # --- chain order ----------------------------------------------------------------------
    def number_chain(
        self,
        known: LssAddress = UNKNOWN,
        *,
        first_id: int = 1,
        count: int | None = None,
        store: bool = True,
        boot_timeout_s: float = 5.0,
        on_module: Callable[[int, LssAddress], None] | None = None,
        settle_asks: int = CHAIN_SETTLE_ASKS,
    ) -> list[tuple[int, LssAddress]]:
        """Number the modules of a chain first_id, first_id + 1, ... in chain order: fastscan
        finds the one module without an id whose enable input is high, it gets the next id
        (stored if `store`), and its boot-up (which raises its enable output) is awaited before
        the next fastscan. Ends when no module answers (asked `settle_asks` times after a boot-up:
        the next module sees its enable input rise a little later) or after `count` modules.
        Without a chain wiring the same loop numbers every board in the order of its address.
        Returns (node id, LSS address) in the order numbered."""
        numbered: list[tuple[int, LssAddress]] = []
        node_id = first_id
        while count is None or len(numbered) < count:
            address = None
            for _ in range(settle_asks if numbered else 1):
                address = self.fastscan(known)
                if address is not None:
                    break
            if address is None:
                break
            with self.boot_up_watch(node_id) as watch:
                self.assign(node_id, store=store)
                watch.wait(boot_timeout_s)
            numbered.append((node_id, address))
            if on_module is not None:
                on_module(node_id, address)
            node_id += 1
        return numbered


@contextlib.contextmanager
def commissioner_on(bus: can.BusABC, *, timeout_s: float = DEFAULT_TIMEOUT_S) -> Iterator[LssCommissioner]:
    """An `LssCommissioner` on a canopen Network of its own on `bus` (the caller's), its receive
    thread running inside the context."""
    network = canopen.Network(bus)
    network.connect()  # the bus is given: this only starts canopen's receive thread
    try:
        yield LssCommissioner(network, timeout_s=timeout_s)
    finally:
        if network.notifier is not None:
            network.notifier.stop(1.0)


class BootUpWatch:
    """Waits for the boot-up message of one node (a context manager: subscribed inside)."""

    def __init__(self, network: canopen.Network, node_id: int) -> None:
        self.network = network
        self.node_id = node_id
        self.cob_id = heartbeat_cob_id(node_id)
        self._booted = threading.Event()

    def _on_frame(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if bytes(data[:1]) == bytes([NmtState.INITIALISING]):
            self._booted.set()

    def __enter__(self) -> Self:
        self.network.subscribe(self.cob_id, self._on_frame)
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.network.unsubscribe(self.cob_id, self._on_frame)

    def wait(self, timeout_s: float) -> None:
        if not self._booted.wait(timeout_s):
            raise NodeSilentError(
                f"node 0x{self.node_id:02X} sent no boot-up within {timeout_s:g} s after LSS gave it its id"
            )


def read_identity(network: canopen.Network, node_id: int, timeout_s: float) -> LssAddress:
    """0x1018 sub 1..4 of node `node_id` over SDO (the verification after LSS)."""
    remote = canopen.RemoteNode(node_id, canopen.ObjectDictionary())
    remote.sdo.RESPONSE_TIMEOUT = timeout_s
    network.add_node(remote)
    try:
        parts = [int.from_bytes(remote.sdo.upload(0x1018, sub)[:4], "little") for sub in range(1, 5)]
    finally:
        del network[node_id]
    return LssAddress(*parts)
