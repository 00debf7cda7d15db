"""A Ray worker's instantiation of its share of the FMUs (docs/scaling.md, "Set-up on a
local Ray cluster"): each shipped file landed once, whatever the number of instances
that use it, and the garbage collector left as it was found; a worker process takes its
instances out of the collector's passes; a worker's start imports no scipy."""
from __future__ import annotations

import faulthandler
import gc
import subprocess
import sys
from collections import Counter

import dsim
from dsim.master.running.backends.ray import worker as ray_worker
from dsim.master.running.backends.ray.backend import RayBackend, _shipped_files
from dsim.master.running.backends.ray.cluster import Shipment


def test_a_worker_lands_each_shipped_file_once_and_gives_the_collector_back(
        built, ray_local, monkeypatch):
    # frame_split: five instances of one ElasticBody FMU, each with its own mesh file
    plan = dsim.prepare(built["ssp"] / "frame_split.ssp")
    shipment = Shipment(ray_local)
    files = [_shipped_files(shipment, spec) for spec in plan.specs]
    landings = Counter()
    real = ray_worker.landed

    def counted(shipped):
        landings[tuple(shipped[:2])] += 1
        return real(shipped)

    monkeypatch.setattr(ray_worker, "landed", counted)
    handler_on = faulthandler.is_enabled()
    frozen = gc.get_freeze_count()
    host = ray_worker.Host()  # the actor's class, in this process
    try:
        place = host.open(plan.specs, files)
        assert len(host.subsystems) == len(plan.specs) == 5
        assert gc.isenabled()
        assert gc.get_freeze_count() == frozen  # this process's objects are not the Host's
    finally:
        host.close()
        if handler_on:  # the worker's crash report replaced pytest's handler
            faulthandler.enable(sys.__stderr__)
    shipped = {tuple(s[:2]) for fmu, scene_files in files
               for s in (fmu, *scene_files.values())}
    fmus = {tuple(fmu[:2]) for fmu, _ in files}
    assert len(fmus) == 1 and len(shipped) == 6  # one FMU file, five mesh files
    assert landings == Counter(dict.fromkeys(shipped, 1))
    assert place["node"] == ray_local.get_runtime_context().get_node_id()


def test_a_worker_process_takes_its_instances_out_of_the_collectors_passes(built,
                                                                           ray_local):
    # chain_10: ten SpringMass instances on two workers; after instantiating, every
    # object of each worker process, its instances' among them, is frozen
    plan = dsim.prepare(built["ssp"] / "chain_10.ssp")
    backend = RayBackend.from_specs(plan.specs)
    try:
        counts = ray_local.get([host.__ray_call__.remote(lambda _: gc.get_freeze_count())
                                for host in backend._cluster.hosts])
        assert len(counts) == 2 and all(count > 1000 for count in counts), counts
    finally:
        backend.close()


def test_the_worker_module_imports_no_scipy():
    # a worker imports this module before its first call; scipy.integrate alone took
    # 0.4 s of every worker's start (only a Model Exchange FMU's step needs it)
    found = subprocess.run([sys.executable, "-c", "import sys; import dsim.master.running."
                            "backends.ray.worker; print(sorted({m.split('.')[0] for m in "
                            "sys.modules} & {'scipy', 'matplotlib', 'lxml', 'rich'}))"],
                           capture_output=True, text=True, check=True)
    assert found.stdout.strip() == "[]", found.stdout
