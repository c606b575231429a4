"""tools/other_project.py's build environment: the lamp, copied outside the checkout, compiled through
ccache as the checkout is, its folder's paths relative."""

from __future__ import annotations

import pytest
from tool_loader import load_tool

other_project = load_tool("other_project")


def test_the_lamp_compiles_through_ccache_with_its_folders_paths_relative(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(other_project.shutil, "which", lambda name: f"/usr/bin/{name}")
    monkeypatch.delenv("CMAKE_CXX_COMPILER_LAUNCHER", raising=False)
    monkeypatch.setenv("CXXFLAGS", "-O1")
    repo = other_project.OUTSIDE
    assert other_project.compiler_cache_env() == {
        "CMAKE_CXX_COMPILER_LAUNCHER": "ccache",
        "CCACHE_BASEDIR": str(repo),
        "CCACHE_NOHASHDIR": "1",
        "CXXFLAGS": f"-O1 -ffile-prefix-map={repo}=.",
    }


def test_no_ccache_or_a_launcher_of_the_users_own_leaves_the_build_as_it_is(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(other_project.shutil, "which", lambda name: None)
    assert other_project.compiler_cache_env() == {}
    monkeypatch.setattr(other_project.shutil, "which", lambda name: f"/usr/bin/{name}")
    monkeypatch.setenv("CMAKE_CXX_COMPILER_LAUNCHER", "sccache")
    assert other_project.compiler_cache_env() == {}
