"""tools/uml/drop_version.py on a program of our own: its need of a glibc version taken out, its
symbol of that version unversioned, and it still starts (bound to the symbol's default version)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from tool_loader import load_tool

drop_version = load_tool("uml/drop_version")

needs_compiler = pytest.mark.skipif(
    shutil.which("cc") is None or shutil.which("readelf") is None, reason="no cc or readelf"
)


def glibc_needs(program: Path) -> set[str]:
    listing = subprocess.run(["readelf", "-V", program], capture_output=True, text=True, check=True).stdout
    return {word for word in listing.split() if word.startswith("GLIBC_")}


def symbol_versions(program: Path) -> dict[str, str]:
    """Undefined symbol -> the version it is bound to ("" for none), as objdump -T lists them."""
    listing = subprocess.run(["objdump", "-T", program], capture_output=True, text=True, check=True).stdout
    versions = {}
    for line in listing.splitlines():
        fields = line.split()
        if "*UND*" in fields and len(fields) >= 5:
            versions[fields[-1]] = fields[-2].strip("()") if "GLIBC" in fields[-2] else ""
    return versions


def compiled(tmp_path: Path, main: str) -> Path:
    """A program of `main`'s C source (with stdlib.h), built by this machine's compiler."""
    source = tmp_path / "exits.c"
    source.write_text(f"#include <stdlib.h>\n{main}\n")
    program = tmp_path / "exits"
    subprocess.run(["cc", "-O0", "-o", program, source], check=True)
    return program


@needs_compiler
def test_a_needed_version_is_taken_out_and_the_program_still_runs(tmp_path: Path) -> None:
    program = compiled(tmp_path, 'int main(void) { return (int)strtol("7", 0, 10); }')
    version = symbol_versions(program)["__libc_start_main"]
    assert version in glibc_needs(program)
    others = [s for s, v in symbol_versions(program).items() if v == version and s != "__libc_start_main"]

    drop_version.drop_version(program, version, ["__libc_start_main", *others])

    assert version not in glibc_needs(program)
    assert symbol_versions(program)["__libc_start_main"] == ""
    assert subprocess.run([program], check=False).returncode == 7


@needs_compiler
def test_a_version_not_needed_or_a_symbol_left_behind_is_refused(tmp_path: Path) -> None:
    program = compiled(tmp_path, "int main(void) { return 0; }")
    before = program.read_bytes()
    with pytest.raises(ValueError, match=r"needs no version GLIBC_9\.99"):
        drop_version.drop_version(program, "GLIBC_9.99", ["__libc_start_main"])
    version = symbol_versions(program)["__libc_start_main"]
    with pytest.raises(ValueError, match="names no no_such_symbol"):
        drop_version.drop_version(program, version, ["__libc_start_main", "no_such_symbol"])
    assert program.read_bytes() == before, "a refused change leaves the file as it was"
    not_elf = tmp_path / "text"
    not_elf.write_text("hello")
    assert drop_version.main(["drop_version.py", str(not_elf), version, "x"]) == 2
