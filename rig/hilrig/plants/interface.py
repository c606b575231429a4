"""The plant interface: what the rig needs from a model of a board's hardware, whatever it is.

A plant is the hardware around one node: it says which of the node's fields it produces and
which it consumes, and a lockstep cycle of the engine uses it in this order::

    frame = plant.sense()           # its sensors now -> the node's sensor RPDO(s)
    snapshot = plant.truth()        # what the hardware really is now (the trace's truth)
    ...                             # RPDOs + SYNC out, the due TPDOs in
    plant.apply(outputs)            # the node's actuator fields of this cycle (None: none came)
    plant.step(dt_s)                # the physics over one period, holding those outputs

Names tie it to the board's table: `sensor_fields` are HIL inputs (board.toml's `hil_inputs`),
carried by the node's sensor RPDO(s), and `sense()` returns an object with one attribute per
name (a frozen dataclass, so a fault can `dataclasses.replace` a value); `actuator_fields` are
fields of the node's TPDOs, handed to `apply` as the wire values in that order. The truth is an
immutable snapshot per cycle (cheap to keep: the history keeps one per cycle); `truth_matrix`
turns a run of them into columns, one per `truth_fields` name (SI, the unit as the name's
suffix: `load_angle_rad`, `current_a`). `truth_parameters()` are named constants the trace
shows beside the truth (a spring's stiffness).

Determinism is the plant's promise: the same seed, the same outputs applied and the same steps
give the same sensor frames and truth, run after run (noise from a seeded generator, no clock).

Implementations: the demo joint (`hilrig.plants.joint.JointModel`: `JointPlant` and its
`SensorModel`), a module of the MuJoCo chain (`hilrig.plants.chain.ChainPhysics.models`, whose
`step` the chain takes for all its modules at once), and any project's own (a class with these
members; nothing to inherit). The engine, the session and the tracer know plants only by this.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

Value = float | int
"""A field's wire value (what a PDO carries)."""


@runtime_checkable
class Plant(Protocol):
    """A board's hardware model, as the engine drives it (see the module docstring)."""

    @property
    def sensor_fields(self) -> tuple[str, ...]:
        """HIL input fields `sense()` gives a value of, every cycle."""
        ...

    @property
    def actuator_fields(self) -> tuple[str, ...]:
        """TPDO fields `apply()` takes, in this order."""
        ...

    @property
    def truth_fields(self) -> tuple[str, ...]:
        """Names of the truth's quantities, SI with the unit in the name: `truth_matrix`'s
        columns."""
        ...

    def sense(self) -> Any:
        """This cycle's sensor readings: an object with an attribute per `sensor_fields` name,
        its wire value (noise drawn from the plant's own seeded stream)."""
        ...

    def truth(self) -> Any:
        """An immutable snapshot of the hardware now (kept per cycle by the history)."""
        ...

    def truth_matrix(self, snapshots: Sequence[Any]) -> np.ndarray:
        """`snapshots` (of `truth()`) as a float64 array, a row per snapshot, a column per
        `truth_fields` name."""
        ...

    def truth_parameters(self) -> Mapping[str, float]:
        """Named constants of the hardware the trace shows beside the truth (SI, unit in the
        name); empty if none."""
        ...

    def apply(self, outputs: Sequence[Value] | None) -> None:
        """The node's `actuator_fields` values of this cycle (wire values), held over the next
        `step`; None when the node sent none (not operational, or lost): the hardware's safe
        default, as a driver whose command stream stopped."""
        ...

    def step(self, dt_s: float) -> None:
        """Advance the physics by `dt_s` [s] with the outputs last applied."""
        ...


__all__ = ["Plant", "Value"]
