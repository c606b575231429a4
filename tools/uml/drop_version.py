"""Let Debian's newer user-mode-linux binary start on an older glibc (tools/uml-kernel): the
symbols named take no version, and the binary's need of the glibc version that brought them is
taken out, so that the loader neither looks for that version nor binds them to it:
tools/uml/isoc23.c's definitions, linked in before glibc, serve them.

    python drop_version.py ELF VERSION SYMBOL...    # e.g. linux.uml GLIBC_2.38 __isoc23_strtol

Edits the file in place; exits 2 with one line if the file is not a 64-bit little-endian ELF
that names each SYMBOL with VERSION.
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path

SHT_DYNSYM = 11
SHT_GNU_VERNEED = 0x6FFFFFFE
SHT_GNU_VERSYM = 0x6FFFFFFF
VER_NDX_GLOBAL = 1


def _cstring(data: bytes | bytearray, offset: int) -> str:
    return bytes(data[offset : data.index(b"\0", offset)]).decode()


def drop_version(path: Path, version: str, symbols: list[str]) -> None:
    data = bytearray(path.read_bytes())
    if data[:4] != b"\x7fELF" or data[4] != 2 or data[5] != 1:
        raise ValueError(f"{path}: not a 64-bit little-endian ELF file")
    (shoff,) = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + k * shentsize) for k in range(shnum)]
    by_type = {s[1]: s for s in sections}
    if not {SHT_DYNSYM, SHT_GNU_VERNEED, SHT_GNU_VERSYM} <= by_type.keys():
        raise ValueError(f"{path}: no versioned dynamic symbols")
    verneed = by_type[SHT_GNU_VERNEED]
    strtab = sections[verneed[6]][4]  # sh_link: the string table the entries name into
    # The version's entry among the needs of its library: taken out of that library's chain
    # (its count one less, the entry before it pointing past it), its index kept (vna_other).
    index = None
    offset = verneed[4]
    while index is None:
        _, count, _, aux, following = struct.unpack_from("<HHIII", data, offset)
        before, aux_offset = None, offset + aux
        for _ in range(count):
            _, _, other, name, aux_next = struct.unpack_from("<IHHII", data, aux_offset)
            if _cstring(data, strtab + name) == version:
                index = other
                if before is None:  # the first: the library's entry starts at the next one
                    struct.pack_into("<I", data, offset + 8, aux + aux_next if aux_next else 0)
                else:
                    skip = aux_offset - before + aux_next if aux_next else 0
                    struct.pack_into("<I", data, before + 12, skip)
                struct.pack_into("<H", data, offset + 2, count - 1)
                break
            before, aux_offset = aux_offset, aux_offset + aux_next
        if not following:
            break
        offset += following
    if index is None:
        raise ValueError(f"{path}: needs no version {version}")
    dynsym, versym = by_type[SHT_DYNSYM], by_type[SHT_GNU_VERSYM]
    dynstr = sections[dynsym[6]][4]
    wanted = set(symbols)
    for k in range(dynsym[5] // 24):
        (name,) = struct.unpack_from("<I", data, dynsym[4] + 24 * k)
        symbol = _cstring(data, dynstr + name)
        if symbol in wanted:
            (current,) = struct.unpack_from("<H", data, versym[4] + 2 * k)
            if current & 0x7FFF != index:
                raise ValueError(f"{path}: {symbol} is not of version {version}")
            struct.pack_into("<H", data, versym[4] + 2 * k, VER_NDX_GLOBAL)
            wanted.discard(symbol)
        elif struct.unpack_from("<H", data, versym[4] + 2 * k)[0] & 0x7FFF == index:
            raise ValueError(f"{path}: {symbol} of version {version} too, not named")
    if wanted:
        raise ValueError(f"{path}: names no {', '.join(sorted(wanted))}")
    temporary = path.with_name(path.name + ".dropping")
    temporary.write_bytes(data)
    temporary.chmod(path.stat().st_mode)
    temporary.replace(path)


def main(argv: list[str]) -> int:
    if len(argv) < 4:
        print("usage: drop_version.py ELF VERSION SYMBOL...", file=sys.stderr)
        return 2
    try:
        drop_version(Path(argv[1]), argv[2], argv[3:])
    except (OSError, ValueError, struct.error) as error:
        print(f"drop_version.py: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
