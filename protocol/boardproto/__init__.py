"""The board's field table (protocol/board.toml) and the generators built on it.

from boardproto import load_table
table = load_table("protocol/board.toml")
table.field("motor_velocity").index      # 0x2100
table.tpdo(2).entries                    # default mapping of TPDO2
"""

from boardproto.loader import TableError, load_table, parse_table
from boardproto.table import (
    Access,
    BoardTable,
    DataType,
    Field,
    HilIo,
    IoDirection,
    Kind,
    NodeIdentity,
    Pdo,
    PdoDirection,
    PdoEntry,
    UnknownNameError,
)

__all__ = [
    "Access",
    "BoardTable",
    "DataType",
    "Field",
    "HilIo",
    "IoDirection",
    "Kind",
    "NodeIdentity",
    "Pdo",
    "PdoDirection",
    "PdoEntry",
    "TableError",
    "UnknownNameError",
    "load_table",
    "parse_table",
]
