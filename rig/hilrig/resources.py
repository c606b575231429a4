"""Where the board's files are: the field table, the EDS and DBC generated from it, the
firmware. Every default path of hilrig comes from here; three cases:

- a checkout (this file is rig/hilrig/resources.py beside protocol/board.toml): the checkout's
  table, the EDS and DBC `make build` generates into build/protocol/, build/bin/joint-firmware
  (build/release/bin/ under user-mode Linux, `$HIL_BUS_PATH` "uml:...", where ASan cannot run);
- an installed wheel: the table, EDS and DBC packaged in hilrig/data/ (generated from the table
  when the wheel was built, `make dist`); the firmware is not in the wheel: build/bin/joint-firmware
  under the working directory (the runtime image's /src);
- the robot head module's table (HEAD_TABLE, protocol/boards/head.toml) and firmware
  (build/bin/head-firmware), the second board, found the same way;
- another table (`--table FILE`, in either case): its EDS and DBC generated on first use with
  boardproto's generators into a cache directory, by content ($XDG_CACHE_HOME/hilrig/tables/).

Which table a command uses when none is given is the project's (`chosen_table`, in the order of
TABLE_ORDER).
"""

from __future__ import annotations

import configparser
import hashlib
import os
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from hilrig.errors import ConfigurationError

_PACKAGE = Path(__file__).resolve().parent


def _checkout_root() -> Path | None:
    root = _PACKAGE.parents[1]
    is_checkout = _PACKAGE.parent.name == "rig" and (root / "protocol" / "board.toml").is_file()
    return root if is_checkout else None


CHECKOUT: Path | None = _checkout_root()
"""The repository root when hilrig runs from a checkout (editable install or PYTHONPATH), else None."""

PACKAGED = _PACKAGE / "data"
"""The wheel's copies of board.toml, board.eds and board.dbc (hilrig ships C extensions, so it is
always installed as plain files, never imported from a zip: a path is enough)."""

FIRMWARE_VARIABLE = "HIL_FIRMWARE"
"""The caller's firmware, over every default and a project's `hil_firmware` (a mutant under
`make mutate`); no tool of hilrig sets it."""
BUS_PATH_VARIABLE = "HIL_BUS_PATH"
"""Set by `hilrig bus` (tools/with-vcan) for its command: "native", "vm:<kernel>", "uml:<kernel>"."""


def _default_firmware() -> tuple[Path, str]:
    """The demo joint's firmware when nothing else names one, and why that one. In the checkout
    under user-mode Linux, whose address space has no room for AddressSanitizer's shadow memory,
    `make build`'s release build instead of the ASan one: a default only, below $HIL_FIRMWARE and
    a project's `hil_firmware`."""
    if os.environ.get(FIRMWARE_VARIABLE):
        return Path(os.environ[FIRMWARE_VARIABLE]), f"${FIRMWARE_VARIABLE}"
    if CHECKOUT is None:
        return Path("build") / "bin" / "joint-firmware", "hilrig's default"
    release = CHECKOUT / "build" / "release" / "bin" / "joint-firmware"
    if os.environ.get(BUS_PATH_VARIABLE, "").startswith("uml:") and release.is_file():
        return release, "the checkout's release build: AddressSanitizer cannot run under user-mode Linux"
    return CHECKOUT / "build" / "bin" / "joint-firmware", "the checkout's build"


if CHECKOUT is not None:
    DEFAULT_TABLE = CHECKOUT / "protocol" / "board.toml"
    DEFAULT_EDS = CHECKOUT / "build" / "protocol" / "board.eds"
    DEFAULT_DBC = CHECKOUT / "build" / "protocol" / "board.dbc"
    REBUILD_HINT = "run `make build`"
else:
    DEFAULT_TABLE = PACKAGED / "board.toml"
    DEFAULT_EDS = PACKAGED / "board.eds"
    DEFAULT_DBC = PACKAGED / "board.dbc"
    REBUILD_HINT = "reinstall hilrig"
DEFAULT_FIRMWARE, DEFAULT_FIRMWARE_ORIGIN = _default_firmware()

# The second board of this repository, the robot head module: its table beside the
# joint's and its firmware beside the joint's; its EDS and DBC come from board_files(HEAD_TABLE).
HEAD_TABLE = (CHECKOUT / "protocol" / "boards" if CHECKOUT is not None else PACKAGED / "boards") / "head.toml"
HEAD_FIRMWARE = DEFAULT_FIRMWARE.with_name("head-firmware")
if not HEAD_FIRMWARE.exists() and CHECKOUT is not None:
    # $HIL_FIRMWARE names a build without the head (a mutant's folder holds only the joint's).
    HEAD_FIRMWARE = CHECKOUT / "build" / "bin" / "head-firmware"
_BUILT_TABLES = {HEAD_TABLE: CHECKOUT / "build" / "protocol" / "head"} if CHECKOUT is not None else {}
"""Tables besides the default whose EDS and DBC `make build` generates (CMake's hil_board_protocol)."""

VIRT_IMAGE = (
    (CHECKOUT if CHECKOUT is not None else Path.cwd())
    / "build"
    / "qemu-virt"
    / "bin"
    / "joint-firmware-virt.elf"
)
"""The demo joint's bare-metal image for qemu's Arm `virt` machine (`make baremetal`), which
`--firmware-platform qemu-virt` runs (hilrig.session.baremetal)."""

JOINT_FMU_DIR = (CHECKOUT if CHECKOUT is not None else Path.cwd()) / "build" / "fmu"
"""Where `make build` writes the demo joint's own FMU and its map (`hilrig.apps.joint_fmu`)."""
JOINT_FMU = JOINT_FMU_DIR / "joint.fmu"
JOINT_FMU_MAP = JOINT_FMU_DIR / "joint.map.toml"

EDS_HINT = f"{REBUILD_HINT}, or give --eds FILE"
DBC_HINT = f"{REBUILD_HINT}, or give --dbc FILE"
FIRMWARE_HINT = "build it with `make build`" if CHECKOUT is not None else "give --firmware FILE"


@dataclass(frozen=True)
class BoardFiles:
    """A table and the EDS and DBC that belong to it."""

    table: Path
    eds: Path
    dbc: Path


TABLE_ENV = "HIL_TABLE"
"""The environment variable that names the table of every command that is given none."""
TABLE_INI_OPTION = "hil_table"
"""The pytest.ini option (section [pytest]) that names the project's table, relative to the file;
hilrig's pytest plugin reads the same one."""
PROJECT_INI = "pytest.ini"
PROJECT_TABLE = "board.toml"

TABLE_ORDER = (
    f"${TABLE_ENV}, else {TABLE_INI_OPTION} of a {PROJECT_INI} in the working folder "
    f"(relative to that file), else a {PROJECT_TABLE} in the working folder, else hilrig's demo board "
    "(the joint's)"
)
"""Where a command's table comes from when it is given no --table, first found wins
(`chosen_table`): what `--help` says."""


@dataclass(frozen=True)
class TableChoice:
    """The table a command uses and why: `source` is '--table', '$HIL_TABLE', 'hil_table of
    pytest.ini in this folder', 'board.toml in this folder' or 'the default'."""

    path: Path
    source: str

    @property
    def is_default(self) -> bool:
        return is_default_table(self.path)


def chosen_table(
    given: Path | None = None, *, cwd: Path | None = None, environ: Mapping[str, str] | None = None
) -> TableChoice:
    """The table of a command: `given` (its --table), else the first of TABLE_ORDER. A name that
    points at no file is a ConfigurationError saying where it was named; a table that is there
    but wrong is the loader's TableError later, as for --table."""
    folder = Path.cwd() if cwd is None else cwd
    environ = os.environ if environ is None else environ
    if given is not None:
        return TableChoice(given, "--table")
    named = environ.get(TABLE_ENV, "").strip()
    if named:
        return TableChoice(_existing(folder / named, f"${TABLE_ENV}"), f"${TABLE_ENV}")
    ini = folder / PROJECT_INI
    from_ini = _ini_table(ini) if ini.is_file() else None
    if from_ini is not None:
        where = f"{TABLE_INI_OPTION} of {PROJECT_INI} in this folder"
        return TableChoice(_existing(folder / from_ini, where), where)
    project = folder / PROJECT_TABLE
    if project.is_file():
        return TableChoice(project, f"{PROJECT_TABLE} in this folder")
    return TableChoice(DEFAULT_TABLE, "the default")


def _ini_table(ini: Path) -> str | None:
    """The hil_table value of a pytest.ini's [pytest] section, as pytest reads it; None: not set."""
    parser = configparser.ConfigParser(interpolation=None)
    try:
        parser.read(ini, encoding="utf-8")
    except (configparser.Error, UnicodeDecodeError) as error:
        raise ConfigurationError(
            f"{ini} is not an ini file hilrig can read ({error}); fix it or give --table"
        ) from None
    value = parser.get("pytest", TABLE_INI_OPTION, fallback="").strip()
    return value or None


def _existing(path: Path, where: str) -> Path:
    if not path.is_file():
        raise ConfigurationError(f"{where} names {path}, which is no file; fix it or give --table")
    return path


def board_files(table: Path | None = None) -> BoardFiles:
    """The files of `table` (None: the default table). The default table's are the checkout's
    build/protocol/ or the packaged ones, which may be missing in a checkout before `make build`
    (callers say EDS_HINT then); the head's those `make build` generates into build/protocol/head/
    when they are there; any other table's are generated now (a bad table: TableError)."""
    if table is None or is_default_table(table):
        return BoardFiles(DEFAULT_TABLE, DEFAULT_EDS, DEFAULT_DBC)
    built = _BUILT_TABLES.get(table)
    if built is not None and (built / "board.eds").is_file():
        return BoardFiles(table, built / "board.eds", built / "board.dbc")
    return generated_files(table)


def eds_for(table: Path | None = None) -> Path:
    return board_files(table).eds


def dbc_for(table: Path | None = None) -> Path:
    return board_files(table).dbc


def is_default_table(table: Path) -> bool:
    try:
        return table.resolve() == DEFAULT_TABLE.resolve()
    except OSError:
        return False


def generated_files(table: Path) -> BoardFiles:
    """The EDS and DBC of `table`, generated into the cache as the build generates the default
    table's. Regenerated on every call (a few milliseconds) but rewritten only when the text
    changed, so a newer boardproto never leaves a stale file behind."""
    from boardproto import load_table
    from boardproto.dbc import generate_dbc
    from boardproto.eds import generate_eds
    from boardproto.outputs import write_if_changed

    board = load_table(table)
    out_dir = _cache_dir() / hashlib.sha256(table.read_bytes()).hexdigest()[:16]
    files = BoardFiles(table, out_dir / "board.eds", out_dir / "board.dbc")
    write_if_changed(files.eds, generate_eds(board))
    write_if_changed(files.dbc, generate_dbc(board))
    return files


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    path = Path(base) / "hilrig" / "tables"
    try:
        path.mkdir(parents=True, exist_ok=True)
        writable = os.access(path, os.W_OK)  # it may exist on a home mounted read-only (a VM)
    except OSError:
        writable = False
    if not writable:  # a read-only home (a container, the micro-VM): the temporary directory instead
        path = Path(tempfile.gettempdir()) / f"hilrig-{os.getuid()}" / "tables"
        path.mkdir(parents=True, exist_ok=True)
    return path


def checkout_version() -> str:
    """rig/pyproject.toml's version, for a checkout whose hilrig is not installed."""
    import tomllib

    if CHECKOUT is None:
        return "unknown (not installed)"
    try:
        text = (CHECKOUT / "rig" / "pyproject.toml").read_text()
        return str(tomllib.loads(text)["project"]["version"]) + " (not installed)"
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return "unknown (not installed)"
