"""board.toml's [[pdo_profile]]s: other mappings of the same PDO slots (`hilrig pdo apply`,
`hilrig bus-load --profile`), each read with the loader's own PDO rules."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from boardproto.cia301 import LAST_SYNCHRONOUS_TYPE, SYNC_COUNTER_MAX
from boardproto.loader import TableError, _array_of_tables, _check_name, _Entry, _load_pdos, _unique_names
from boardproto.table import FULL_PDO_PROFILE, ObjectEntry, Pdo, PdoDirection, PdoProfile

_PROFILE_REQUIRED_KEYS = frozenset({"name", "description"})
_PROFILE_OPTIONAL_KEYS = frozenset({"rpdo", "tpdo", "sync_counter_overflow"})


def load_pdo_profiles(
    source: Path,
    document: Mapping[str, Any],
    slots: tuple[int, int],
    entries_by_name: Mapping[str, ObjectEntry],
    default: tuple[tuple[Pdo, ...], tuple[Pdo, ...]],
) -> tuple[PdoProfile, ...]:
    """The [[pdo_profile]]s; one without rpdo/tpdo is the table's own mapping (its name must be
    FULL_PDO_PROFILE), which is also there when board.toml names no profile."""
    for pdo in (*default[0], *default[1]):
        if pdo.sync_start:
            raise TableError(
                f"{source}: {pdo.name}: sync_start only in a [[pdo_profile]] (the firmware's default "
                "mapping runs without the SYNC counter)"
            )
    profiles: list[PdoProfile] = []
    for position, data in enumerate(_array_of_tables(source, document, "pdo_profile")):
        name_hint = data.get("name") if isinstance(data, Mapping) else None
        entry = _Entry(source, f"pdo_profile {name_hint or position + 1}", data)
        entry.check_keys(_PROFILE_REQUIRED_KEYS, _PROFILE_OPTIONAL_KEYS)
        name, description = _check_name(entry), entry.text("description")
        overflow = entry.integer("sync_counter_overflow", 0, SYNC_COUNTER_MAX, default=0)
        if overflow == 1:
            raise entry.error("sync_counter_overflow: 0 (no SYNC counter) or 2..240")
        if "rpdo" not in entry.data and "tpdo" not in entry.data:
            if name != FULL_PDO_PROFILE:
                raise entry.error(f"maps no PDO: only {FULL_PDO_PROFILE!r} is the table's own mapping")
            rpdos, tpdos = default
        else:
            rpdos = _load_pdos(source, entry.data, PdoDirection.RPDO, slots[0], entries_by_name)
            tpdos = _load_pdos(source, entry.data, PdoDirection.TPDO, slots[1], entries_by_name)
        for pdo in (*rpdos, *tpdos):
            if pdo.sync_start and (
                pdo.direction is not PdoDirection.TPDO
                or not 1 <= pdo.transmission_type <= LAST_SYNCHRONOUS_TYPE
            ):
                raise entry.error(
                    f"{pdo.name}: sync_start needs a TPDO of transmission type 1..240 (every n-th SYNC)"
                )
        for pdo in tpdos:
            if pdo.enabled and pdo.sync_start and (not overflow or overflow % pdo.transmission_type):
                raise entry.error(
                    f"{pdo.name}: sync_start needs a sync_counter_overflow that type "
                    f"{pdo.transmission_type} divides (the counter wraps without shifting its phase)"
                )
        profiles.append(PdoProfile(name, description, rpdos, tpdos, overflow))
    if FULL_PDO_PROFILE not in {p.name for p in profiles}:
        profiles.insert(0, PdoProfile(FULL_PDO_PROFILE, "the table's own PDO mapping", *default))
    _unique_names(source, "pdo_profile", profiles)
    return tuple(profiles)
