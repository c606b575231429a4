"""Fuzzer for the field-table loader: `load_table` on any bytes either returns a valid table
or raises `TableError` with a one-line message naming the file. Any other exception, a
multi-line message, or a returned table the generators cannot render is a finding.

Runs under atheris (libFuzzer for Python) when it is importable; otherwise a seeded mutation
fuzzer with the same invariant (`--mutate`). `make fuzz` and the short run in `make test` go
through firmware/canopen/fuzz/run-fuzzers, which installs atheris into build/fuzz/pylib.

  PYTHONPATH=build/fuzz/pylib:protocol .venv/bin/python protocol/fuzz/fuzz_table.py \
      -seed=1 -runs=2000 build/fuzz/corpus/table protocol/fuzz/corpus     # atheris
  PYTHONPATH=protocol .venv/bin/python protocol/fuzz/fuzz_table.py --mutate 2000 \
      protocol/fuzz/corpus                                                # fallback
  ... fuzz_table.py crash-FILE                                            # reproduce one
"""

from __future__ import annotations

import hashlib
import os
import random
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

try:
    import atheris
except ImportError:  # the fallback mutation fuzzer below needs nothing but the stdlib
    atheris = None

if atheris is not None:
    with atheris.instrument_imports():
        from boardproto import BoardTable, TableError, load_table
        from boardproto.cpp_header import generate_header
        from boardproto.vectors import generate_field_vectors
else:
    from boardproto import BoardTable, TableError, load_table
    from boardproto.cpp_header import generate_header
    from boardproto.vectors import generate_field_vectors


class InvariantError(AssertionError):
    """`load_table` broke its contract on one input."""


def _check_valid(table: BoardTable) -> None:
    """What "a valid table" promises the generators and the firmware."""
    objects = [*table.fields, *table.hil_inputs, *table.hil_outputs]
    if len({o.name for o in objects}) != len(objects) or len({o.index for o in objects}) != len(objects):
        raise InvariantError("accepted a table with duplicate names or indices")
    if not all(0x2000 <= o.index <= 0x5FFF for o in objects):
        raise InvariantError("accepted an index outside the manufacturer range")
    for pdo in (*table.rpdos, *table.tpdos):
        if sum(e.bits for e in pdo.entries) > 64:
            raise InvariantError(f"accepted {pdo.name} longer than 8 bytes")
    generate_header(table)
    generate_field_vectors(table)


def check_one(data: bytes, path: Path) -> None:
    """Write `data` to `path`, load it, and raise InvariantError (or let any other exception
    through) when the contract is broken."""
    path.write_bytes(data)
    try:
        table = load_table(path)
    except TableError as error:
        message = str(error)
        if "\n" in message or "\r" in message:
            raise InvariantError(f"TableError message is not one line: {message!r}") from error
        if not message.startswith(f"{path}: "):
            raise InvariantError(f"TableError message does not name the file: {message!r}") from error
        return
    _check_valid(table)


def _scratch_file() -> Path:
    directory = Path(tempfile.mkdtemp(prefix="fuzz_table."))
    return directory / "board.toml"


# --- atheris -----------------------------------------------------------------------------------


def run_atheris(argv: list[str]) -> None:
    path = _scratch_file()

    def test_one(data: bytes) -> None:
        check_one(data, path)

    atheris.Setup(argv, test_one)
    atheris.Fuzz()


# --- fallback: seeded mutation fuzzer ------------------------------------------------------------

_TOKENS = (
    b"[node]",
    b"[[field]]",
    b"[[hil_input]]",
    b"[[hil_output]]",
    b"[pdo]",
    b"[[rpdo]]",
    b"[[tpdo]]",
    b" = ",
    b'"',
    b"\n",
    b"0x",
    b"-1",
    b"1e999",
    b"nan",
    b"inf",
    b"true",
    b"[]",
    b"{}",
    b'map = ["',
    b"number = ",
    b"\\u0000",
    b"\\n",
    b"0x7FF",
    b"0xFFFFFFFFF",
)


def mutate(data: bytes, other: bytes, rng: random.Random) -> bytes:
    """One to four random edits: flip, insert, delete, duplicate, token, splice."""
    buffer = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(6)
        at = rng.randint(0, len(buffer))
        if op == 0 and buffer:
            buffer[min(at, len(buffer) - 1)] ^= 1 << rng.randrange(8)
        elif op == 1:
            buffer[at:at] = bytes([rng.randrange(256)])
        elif op == 2 and buffer:
            del buffer[at : at + rng.randint(1, 64)]
        elif op == 3 and buffer:
            start = rng.randrange(len(buffer))
            buffer[at:at] = buffer[start : start + rng.randint(1, 64)]
        elif op == 4:
            buffer[at:at] = rng.choice(_TOKENS)
        elif other:
            start = rng.randrange(len(other))
            buffer[at:] = other[start:]
    return bytes(buffer)


def run_mutation(runs: int, seed: int, corpus_dirs: Sequence[Path], crash_dir: Path) -> int:
    seeds = [p.read_bytes() for d in corpus_dirs for p in sorted(d.iterdir()) if p.is_file()]
    if not seeds:
        print("fuzz_table: no seeds in " + ", ".join(map(str, corpus_dirs)), file=sys.stderr)
        return 2
    rng = random.Random(seed)
    path = _scratch_file()
    for run in range(runs):
        data = mutate(rng.choice(seeds), rng.choice(seeds), rng)
        try:
            check_one(data, path)
        except Exception as error:  # any exception is the finding being looked for
            crash_dir.mkdir(parents=True, exist_ok=True)
            crash = crash_dir / f"crash-{hashlib.sha1(data).hexdigest()}"
            crash.write_bytes(data)
            print(f"fuzz_table: run {run}: {type(error).__name__}: {error}", file=sys.stderr)
            print(f"fuzz_table: reproduce: PYTHONPATH=protocol {sys.executable} {__file__} {crash}")
            return 1
    print(f"#{runs} DONE (mutation fuzzer, seed {seed}): no finding")
    return 0


def reproduce(files: Sequence[Path]) -> int:
    path = _scratch_file()
    for file in files:
        check_one(file.read_bytes(), path)  # raises on a finding
        print(f"{file}: ok")
    return 0


def main(argv: list[str]) -> int:
    args = argv[1:]
    if args and args[0] == "--mutate":
        runs = int(args[1])
        seed = int(os.environ.get("FUZZ_SEED", "1"))
        crash_dir = Path(os.environ.get("FUZZ_CRASH_DIR", "."))
        return run_mutation(runs, seed, [Path(a) for a in args[2:]], crash_dir)
    if atheris is None:
        files = [Path(a) for a in args if not a.startswith("-")]
        if files and all(f.is_file() for f in files):
            return reproduce(files)
        print("fuzz_table: atheris is not installed: use --mutate RUNS CORPUS_DIR...", file=sys.stderr)
        return 2
    run_atheris(argv)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
