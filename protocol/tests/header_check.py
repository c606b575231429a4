"""The one compile check of the generated CiA headers (`board/cia301.hpp`, `cia302.hpp`,
`cia305.hpp`): a source that includes the header and holds static_asserts of the Python values,
compiled with the project's warning flags."""

from __future__ import annotations

import subprocess
from pathlib import Path

WARNING_FLAGS = "-std=c++20 -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Werror -fsyntax-only"


def compile_header_check(
    generated_dir: Path, scratch: Path, header: str, namespace: str, asserts: str
) -> subprocess.CompletedProcess[str]:
    """g++ on `#include "board/<header>"`, `using namespace <namespace>;` and `asserts`."""
    source = scratch / "check.cpp"
    source.write_text(f'#include "board/{header}"\nusing namespace {namespace};\n{asserts}\n')
    return subprocess.run(
        ["g++", *WARNING_FLAGS.split(), f"-I{generated_dir / 'include'}", str(source)],
        capture_output=True,
        text=True,
        check=False,
    )
