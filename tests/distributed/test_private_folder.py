"""Folders with fixed names in the shared temporary directory (a Ray worker's landed
FMUs and crash report, the driver's Ray log: master/running/private_folder.py), attacked
the way another user of the machine could: the folder made first by someone else, a
link in its place, a folder others may write to.  None is used; the process works in a
new folder of its own, and what the attacker left there is neither read nor written."""
import os
import stat
import tempfile
from pathlib import Path

import pytest

from dsim.master.running import private_folder as module
from dsim.master.running.backends.ray.worker import fault_file
from dsim.master.running.private_folder import private_folder
from dsim.master.running.backends.ray.cluster import Shipment, landed, ray_log

#: a user id that is not this process's (nobody), for a folder someone else made
NOBODY = 65534


@pytest.fixture
def shared_tmp(tmp_path, monkeypatch):
    """A temporary directory of the test's, as /tmp is (sticky, everyone may write),
    in place of the machine's, and no fallback folder remembered from before."""
    root = tmp_path / "tmp"
    root.mkdir()
    root.chmod(0o1777)
    monkeypatch.setattr(tempfile, "tempdir", str(root))
    monkeypatch.setattr(module, "_instead", {})
    return root


def planted(folder: Path, how: str, victim: Path) -> None:
    """Leave ``folder`` as an attacker would: ``others`` (made by another user, everyone
    may write), ``writable`` (ours, but others may write), or ``link`` (a link to a
    folder of the attacker's); in the first two, a link to ``victim`` at each name a
    worker would write, and a file where it would find a landed FMU."""
    if how == "link":
        elsewhere = folder.parent / f"attacker-{folder.name}"
        elsewhere.mkdir()
        folder.symlink_to(elsewhere, target_is_directory=True)
        return
    folder.mkdir()
    for pid in (os.getpid(), os.getpid() + 1):
        (folder / f"fault-{pid}.txt").symlink_to(victim)
        (folder / f"ray-{pid}.log").symlink_to(victim)
    folder.chmod(0o777)
    if how == "others":
        if os.geteuid() != 0:
            pytest.skip("making a folder another user owns needs root")
        for path in [folder, *folder.iterdir()]:
            os.lchown(path, NOBODY, NOBODY)


@pytest.mark.parametrize("how", ["others", "writable", "link"])
def test_a_folder_another_user_could_have_made_is_never_used(shared_tmp, tmp_path, how):
    victim = tmp_path / "victim.txt"
    victim.write_text("the user's own file\n")
    worker = shared_tmp / f"dsim-worker-{os.getuid()}"  # crash reports, landed FMUs
    driver = shared_tmp / f"dsim-{os.getuid()}"  # what Ray's processes said
    for folder in (worker, driver):
        planted(folder, how, victim)
    for folder, path in ((worker, fault_file(os.getpid())), (driver, ray_log())):
        instead = path.parent
        assert instead != folder and instead.parent == shared_tmp, (folder, instead)
        info = os.lstat(instead)
        assert stat.S_ISDIR(info.st_mode) and stat.S_IMODE(info.st_mode) == 0o700
        assert private_folder(folder) == instead  # the same for the whole process
        with open(path, "w") as written:  # what a worker and the driver do
            written.write("Fatal Python error: Aborted\n")
    assert victim.read_text() == "the user's own file\n"


def test_a_missing_folder_is_made_for_this_user_only(shared_tmp):
    folder = shared_tmp / f"dsim-worker-{os.getuid()}"
    assert private_folder(folder) == folder
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    folder.chmod(0o755)  # made so by an earlier dsim: others may read, not write
    assert private_folder(folder) == folder


def test_a_worker_never_loads_an_fmu_planted_where_it_lands_shipped_files(
        shared_tmp, tmp_path, ray_local):
    """The driver's FMU is not on this node (another machine's path): the worker lands
    the shipped bytes, not the file an attacker put at the landing path first."""
    real = tmp_path / "Model.fmu"
    real.write_bytes(b"the real FMU")
    path, digest, ref = Shipment(ray_local).add(real)
    elsewhere = str(tmp_path / "on-another-machine" / "Model.fmu")
    folder = shared_tmp / f"dsim-worker-{os.getuid()}"
    folder.mkdir()
    (folder / digest[:32]).mkdir()
    (folder / digest[:32] / "Model.fmu").write_bytes(b"the attacker's FMU")
    for path_ in [folder, *folder.rglob("*")]:
        path_.chmod(0o777)
    if os.geteuid() == 0:
        for path_ in [folder, *folder.rglob("*")]:
            os.lchown(path_, NOBODY, NOBODY)
    target = landed((elsewhere, digest, ref))
    assert target.read_bytes() == b"the real FMU"
    assert not target.is_relative_to(folder)


def test_empty_crash_reports_of_ended_workers_are_swept_a_crash_is_kept(shared_tmp):
    """A worker killed without a crash leaves an empty report nobody reads (before this
    release every worker made one, spares too): the next worker of the node removes
    those of ended processes; one with a crash in it, and a live process's, stay."""
    import subprocess
    import sys

    from dsim.master.running.backends.ray.worker import sweep_reports

    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()
    folder = fault_file(os.getpid()).parent
    empty, crashed, live = (folder / f"fault-{ended.pid}.txt",
                            folder / f"fault-{ended.pid + 100000000}.txt",
                            folder / f"fault-{os.getpid()}.txt")
    empty.touch()
    crashed.write_text("Fatal Python error: Segmentation fault\n")
    live.touch()
    assert sweep_reports(folder) == [empty]
    assert not empty.exists() and crashed.exists() and live.exists()
