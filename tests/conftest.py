"""Shared fixtures: the FMUs and scene archives are built once per session
(skipped when up to date), so `pytest` alone works on a fresh checkout."""
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def built():
    """Paths of build/fmus and build/ssp after building what is out of date."""
    from build_fmus.build import build_fmus, pack_scenes

    build_fmus(log=lambda message: None)
    pack_scenes(log=lambda message: None)
    return {"fmus": ROOT / "build" / "fmus", "ssp": ROOT / "build" / "ssp"}


@pytest.fixture(scope="session")
def block_fmus(tmp_path_factory):
    """The plain-C block FMU (tests/third_party/block.c) compiled with gcc, with and
    without state saving."""
    from tests.third_party.build import c_fmu

    folder = tmp_path_factory.mktemp("block")
    return {"state": c_fmu(folder, "block"),
            "nostate": c_fmu(folder, "block_nostate", can_save_state=False)}
