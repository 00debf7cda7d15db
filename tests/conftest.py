"""Shared fixtures: the FMUs and scene archives are built once per session
(skipped when up to date), so `pytest` alone works on a fresh checkout."""
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session")
def built():
    """Paths of build/fmus and build/ssp after building what is out of date."""
    from dsim.build_fmus.build import build_fmus, pack_scenes

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


@pytest.fixture(scope="session")
def ray_local():
    """One local Ray instance for the whole session's Ray tests (2 CPUs, a small object
    store, no dashboard): dsim's Ray backends and sweeps join it rather than start
    their own, as they join any Ray instance their process is connected to."""
    import logging
    import signal

    import ray

    previous = signal.getsignal(signal.SIGTERM)  # ray.init replaces it
    ray.init(address="local", num_cpus=2, include_dashboard=False,
             object_store_memory=100 * 1024 ** 2, log_to_driver=False,
             logging_level=logging.ERROR)
    signal.signal(signal.SIGTERM, previous)
    yield ray
    ray.shutdown()


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    """End the test process as the dsim command ends (master/tools/process_exit.py): without
    the native exit handlers of the FMU libraries loaded in it.  pythonfmu's library
    cannot be unloaded and releases its interpreter state twice at exit, which now and
    then aborts a process that has finished all its work; pytest's own work is done
    here (its report printed, its cache written)."""
    import atexit
    import os
    import sys

    status = getattr(config, "_dsim_exit_status", None)
    if status is None:
        return
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(int(status))


def pytest_sessionfinish(session, exitstatus):
    session.config._dsim_exit_status = exitstatus
