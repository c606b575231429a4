"""A plant that is an FMU: any FMI 2.0 or 3.0 co-simulation FMU as a board's hardware, over FMPy,
tied to the board's HIL I/O by a plant map (`hilrig.plants.fmu_map`, a TOML file next to the
table, checked against modelDescription.xml and the table at load).

    plant = FmuPlant.load("oscillator.map.toml", table.board, seed=1)

Each lockstep cycle: `sense()` gives the mapped outputs (scaled, seeded noise, clamped to the
fields' ranges) and the map's constants; `apply()` sets the mapped inputs from the node's
actuator values (wire 0 when the node sent none); `step(dt)` calls doStep `substeps` times over
the period. The truth is the mapped outputs and the map's [[truth]] variables, read once after
each step. Determinism: the FMU's own stepping plus a seeded generator for the noise; the same
seed and the same outputs applied give the same frames and truth.

Branching: `save_state()` / `restore_state()` take the FMU's state (getFMUstate/setFMUstate)
with the noise generator, the time and the held inputs, where the FMU can
(canGetAndSetFMUstate); an FMU that cannot is branched by re-running from its seed.
"""

from __future__ import annotations

import dataclasses
import shutil
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from boardproto import BoardTable
from hilrig.errors import PlantMapError
from hilrig.plants.fmu_map import PlantMap, load_map
from hilrig.plants.interface import Value


@dataclass(frozen=True)
class FmuSnapshot:
    """Everything `restore_state` needs to go back to a cycle: the FMU's own state (an opaque
    handle the FMU frees with the plant), the noise generator's, the time and the inputs."""

    fmu_state: Any
    rng_state: Mapping[str, Any]
    time_s: float
    inputs: tuple[float, ...]
    values: tuple[float, ...]


class _Fmi2:
    """The few FMI 2.0 co-simulation calls the plant makes, over FMPy's FMU2Slave."""

    def __init__(self, plant_map: PlantMap, directory: str, name: str) -> None:
        from fmpy.fmi2 import FMU2Slave

        self.fmu = FMU2Slave(
            guid=plant_map.guid,
            unzipDirectory=directory,
            modelIdentifier=plant_map.model_identifier,
            instanceName=name,
        )
        self.fmu.instantiate()

    def start(self, parameters: Mapping[int, tuple[str, float]]) -> None:
        self.fmu.setupExperiment(startTime=0.0)
        self._set(parameters)
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def _set(self, parameters: Mapping[int, tuple[str, float]]) -> None:
        for reference, (kind, value) in parameters.items():
            if kind == "Real":
                self.fmu.setReal([reference], [value])
            elif kind == "Integer" or kind == "Enumeration":
                self.fmu.setInteger([reference], [int(value)])
            elif kind == "Boolean":
                self.fmu.setBoolean([reference], [bool(value)])

    def set_reals(self, references: Sequence[int], values: Sequence[float]) -> None:
        self.fmu.setReal(references, values)

    def get_reals(self, references: Sequence[int]) -> list[float]:
        return list(self.fmu.getReal(references))

    def do_step(self, time_s: float, dt_s: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=time_s, communicationStepSize=dt_s)

    def get_state(self) -> Any:
        return self.fmu.getFMUState()

    def set_state(self, state: Any) -> None:
        self.fmu.setFMUState(state)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


class _Fmi3(_Fmi2):
    """The same calls for FMI 3.0, over FMPy's FMU3Slave (Float64 variables)."""

    def __init__(self, plant_map: PlantMap, directory: str, name: str) -> None:
        from fmpy.fmi3 import FMU3Slave

        self.fmu = FMU3Slave(
            guid=plant_map.guid,
            unzipDirectory=directory,
            modelIdentifier=plant_map.model_identifier,
            instanceName=name,
        )
        self.fmu.instantiate()

    def start(self, parameters: Mapping[int, tuple[str, float]]) -> None:
        self._set(parameters)
        self.fmu.enterInitializationMode(startTime=0.0)
        self.fmu.exitInitializationMode()

    def _set(self, parameters: Mapping[int, tuple[str, float]]) -> None:
        for reference, (kind, value) in parameters.items():
            if kind in ("Float64", "Float32"):
                self.fmu.setFloat64([reference], [value])
            elif kind.startswith(("Int", "UInt")) or kind == "Enumeration":
                self.fmu.setInt64([reference], [int(value)])
            elif kind == "Boolean":
                self.fmu.setBoolean([reference], [bool(value)])

    def set_reals(self, references: Sequence[int], values: Sequence[float]) -> None:
        self.fmu.setFloat64(references, values)

    def get_reals(self, references: Sequence[int]) -> list[float]:
        return list(self.fmu.getFloat64(references))

    def do_step(self, time_s: float, dt_s: float) -> None:
        self.fmu.doStep(currentCommunicationPoint=time_s, communicationStepSize=dt_s)


def _release(fmu: _Fmi2, directory: str) -> None:
    try:
        fmu.close()
    finally:
        shutil.rmtree(directory, ignore_errors=True)


class FmuPlant:
    """An FMU behind the plant interface (`hilrig.plants.interface.Plant`; module docstring)."""

    def __init__(self, plant_map: PlantMap, seed: int = 0, params: Mapping[str, float] | None = None) -> None:
        from fmpy import extract

        self.map = plant_map
        parameters = {reference: (kind, value) for reference, kind, value in plant_map.parameters.values()}
        for name, value in (params or {}).items():
            if name not in plant_map.settable:
                raise PlantMapError(
                    f"params: the FMU {plant_map.fmu.name} has no parameter {name!r}: "
                    f"one of {sorted(plant_map.settable)}"
                )
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise PlantMapError(f"params: {name} must be a number, not {value!r}")
            reference, kind = plant_map.settable[name]
            parameters[reference] = (kind, float(value))
        self.parameters = {
            name: float(parameters[reference][1])
            for name, (reference, _) in plant_map.settable.items()
            if reference in parameters
        }
        self._directory = extract(str(plant_map.fmu))
        interface = _Fmi3 if plant_map.fmi_version.startswith("3") else _Fmi2
        try:
            self._fmu = interface(plant_map, self._directory, plant_map.fmu.stem)
        except Exception as error:  # fmpy: a binary missing for this platform, a failed instantiate
            shutil.rmtree(self._directory, ignore_errors=True)
            raise PlantMapError(f"FMU {plant_map.fmu}: cannot instantiate it here ({error})") from None
        self._finalizer = weakref.finalize(self, _release, self._fmu, self._directory)
        self._rng = np.random.default_rng(seed)
        self._time_s = 0.0
        self._in_refs = [link.value_reference for link in plant_map.inputs]
        self._inputs = tuple(link.offset for link in plant_map.inputs)
        self._read_refs = [link.value_reference for link in plant_map.outputs] + [
            truth.value_reference for truth in plant_map.truth
        ]
        self._frame_type = dataclasses.make_dataclass(
            "FmuSensorFrame", plant_map.sensor_fields, frozen=True, slots=True
        )
        self._fmu.start(parameters)
        if self._in_refs:
            self._fmu.set_reals(self._in_refs, self._inputs)
        self._values = tuple(self._fmu.get_reals(self._read_refs)) if self._read_refs else ()

    @classmethod
    def load(
        cls,
        map_path: str | Path,
        table: BoardTable,
        fmu: str | Path | None = None,
        seed: int = 0,
        params: Mapping[str, float] | None = None,
    ) -> FmuPlant:
        """The plant of the map at `map_path`, checked against `table` and the FMU (`fmu`, or
        the map's own `fmu`)."""
        return cls(load_map(map_path, table, fmu), seed, params)

    @property
    def sensor_fields(self) -> tuple[str, ...]:
        return self.map.sensor_fields

    @property
    def actuator_fields(self) -> tuple[str, ...]:
        return self.map.actuator_fields

    @property
    def truth_fields(self) -> tuple[str, ...]:
        return tuple(truth.name for truth in self.map.truth)

    @property
    def time_s(self) -> float:
        """The FMU's time: the sum of the steps so far [s]."""
        return self._time_s

    def sense(self) -> Any:
        values: dict[str, Value] = {}
        for link, value in zip(self.map.outputs, self._values, strict=False):
            noisy = value * link.scale + link.offset
            if link.noise:
                noisy += float(self._rng.normal(0.0, link.noise))
            values[link.field] = min(link.high, max(link.low, round(noisy)))
        values.update(self.map.constants)
        return self._frame_type(**values)

    def truth(self) -> tuple[float, ...]:
        return self._values[len(self.map.outputs) :]

    def truth_matrix(self, snapshots: Sequence[tuple[float, ...]]) -> np.ndarray:
        return np.array(snapshots, dtype=np.float64).reshape(-1, len(self.map.truth))

    def truth_parameters(self) -> Mapping[str, float]:
        return dict(self.parameters)

    def apply(self, outputs: Sequence[Value] | None) -> None:
        wires = outputs if outputs is not None else [0] * len(self.map.inputs)
        self._inputs = tuple(
            float(wire) * link.scale + link.offset for link, wire in zip(self.map.inputs, wires, strict=True)
        )

    def step(self, dt_s: float) -> None:
        if self._in_refs:
            self._fmu.set_reals(self._in_refs, self._inputs)
        substep = dt_s / self.map.substeps
        for index in range(self.map.substeps):
            self._fmu.do_step(self._time_s + index * substep, substep)
        self._time_s += dt_s
        if self._read_refs:
            self._values = tuple(self._fmu.get_reals(self._read_refs))

    def save_state(self) -> FmuSnapshot:
        """This cycle's state, to `restore_state` later (a branch of a scenario)."""
        if not self.map.can_save_state:
            raise PlantMapError(
                f"FMU {self.map.fmu.name} cannot save its state (canGetAndSetFMUstate is false): "
                "branch by running again from the same seed"
            )
        return FmuSnapshot(
            self._fmu.get_state(), self._rng.bit_generator.state, self._time_s, self._inputs, self._values
        )

    def restore_state(self, snapshot: FmuSnapshot) -> None:
        """Go back to the cycle of `snapshot` (the FMU, the noise, the time, the held inputs)."""
        self._fmu.set_state(snapshot.fmu_state)
        self._rng.bit_generator.state = dict(snapshot.rng_state)
        self._time_s, self._inputs, self._values = snapshot.time_s, snapshot.inputs, snapshot.values

    def close(self) -> None:
        """Free the FMU instance and its extracted files (also done when the plant is collected)."""
        self._finalizer()


def fmu_factory(map_path: str | Path, table: BoardTable, fmu: str | Path | None = None) -> Any:
    """A plant factory (`(params, seed) -> Plant`, as `hil_plant` and the session take) for the
    map at `map_path`, checked once now; `params` are FMU parameters by name."""
    plant_map = load_map(map_path, table, fmu)

    def make_plant(params: Mapping[str, float] | None, seed: int) -> FmuPlant:
        if params is not None and not isinstance(params, Mapping):
            raise PlantMapError(
                f"params: an FMU plant takes FMU parameters by name, not {type(params).__name__}"
            )
        return FmuPlant(plant_map, seed, params)

    return make_plant


__all__ = ["FmuPlant", "FmuSnapshot", "fmu_factory"]
