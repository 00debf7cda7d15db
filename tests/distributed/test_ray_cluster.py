"""docs/distributed.md, tested: a two-node Ray cluster on this machine (`ray start
--head`, then `ray start --address` with a resource of its own), started and stopped
by the tests, with token authentication as a real cluster would have; dsim runs a
scene on it with a component placed on the second node, and a sweep."""
import csv
import contextlib
import json
import os
import re
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.support.distributed import free_port
from tests.support.paths import DSIM, ROOT
from tests.support.scenes import placed_scene

RAY = str(Path(sys.executable).parent / "ray")


def start_node(arguments, env, log: Path) -> subprocess.Popen:
    """`ray start ... --block` in its own process group; returns once it is up.  Without
    Ray's log monitor: dsim's drivers take no worker output (``log_to_driver=False``),
    and the monitor costs a node about a second of CPU to start and 4 % of a core while
    it polls the logs."""
    process = subprocess.Popen([RAY, "start", *arguments, "--include-log-monitor=false",
                                "--block"], env=env, cwd=ROOT,
                               stdout=open(log, "w"), stderr=subprocess.STDOUT,
                               start_new_session=True)
    deadline = time.monotonic() + 120
    while "block forever" not in log.read_text():
        if process.poll() is not None or time.monotonic() > deadline:
            stop_node(process)
            pytest.fail(f"ray start {' '.join(arguments)} did not come up:\n{log.read_text()}")
        time.sleep(0.2)
    return process


# What the head's GCS logs when the port it was given was taken between free_port()
# closing its probe and the GCS binding it (other Ray nodes of the suite, run beside
# these tests, take ephemeral ports of their own).
PORT_TAKEN = re.compile(r"Failed to start the grpc server|Address already in use")


def start_head(arguments, env, folder: Path, attempts: int = 3) -> tuple[subprocess.Popen, int]:
    """A head node on a free port, `arguments` beside `--head --port`: its process and its
    port. A port taken in the meantime is a race of the test machine, not of dsim: the
    head is tried again on another port; any other failure fails the test."""
    for attempt in range(attempts):
        port = free_port()
        log = folder / f"head{attempt}.log"
        try:
            return start_node(["--head", f"--port={port}", *arguments], env, log), port
        except pytest.fail.Exception:
            logs = [log.read_text()] + [f.read_text(errors="replace")
                                        for f in folder.glob("session_*/logs/gcs_server.*")]
            if attempt == attempts - 1 or not any(PORT_TAKEN.search(t) for t in logs):
                raise
    raise AssertionError("unreachable")


def stop_node(process: subprocess.Popen) -> None:
    """End the node's process group (only the processes this test started), gently
    first: `ray stop` would end every Ray process of the machine."""
    for number, grace in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 10.0)):
        try:
            os.killpg(process.pid, number)
        except ProcessLookupError:
            break
        try:
            process.wait(timeout=grace)
            break
        except subprocess.TimeoutExpired:
            continue


@pytest.fixture(scope="module")
def cluster():
    """A head node (1 CPU, resource head_node) and a worker node (1 CPU, resource
    right_node); its address and the environment a driver needs (the token)."""
    folder = Path(tempfile.mkdtemp(prefix="dsimray", dir="/tmp"))  # short: socket paths
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
           "RAY_USAGE_STATS_ENABLED": "0", "OMP_NUM_THREADS": "1"}
    nodes = []
    try:
        head, port = start_head(["--num-cpus=1", '--resources={"head_node": 1}',
                                 "--include-dashboard=false", f"--temp-dir={folder}",
                                 "--object-store-memory=100000000"], env, folder)
        nodes.append(head)
        address = f"127.0.0.1:{port}"
        nodes.append(start_node([f"--address={address}", "--num-cpus=1",
                                 '--resources={"right_node": 1}',
                                 "--object-store-memory=100000000"], env, folder / "node.log"))
        yield {"address": address, "env": env}
    finally:
        for node in reversed(nodes):
            stop_node(node)
        shutil.rmtree(folder, ignore_errors=True)


def nodes_with(cluster) -> dict[str, str]:
    """Custom resource -> the id of the node that has it, as the cluster says."""
    script = ("import json, logging, sys, ray\n"
              "ray.init(address=sys.argv[1], logging_level=logging.ERROR)\n"
              "print(json.dumps({r: n['NodeID'] for n in ray.nodes() if n['Alive'] "
              "for r in n['Resources'] if r.endswith('_node')}))\n")
    process = subprocess.run([sys.executable, "-c", script, cluster["address"]],
                             env=cluster["env"], cwd=ROOT, capture_output=True, text=True,
                             timeout=120)
    assert process.returncode == 0, process.stderr
    return json.loads(process.stdout.strip().splitlines()[-1])


def test_a_run_on_the_cluster_places_components_on_their_nodes(built, cluster, tmp_path):
    folder = placed_scene(built, tmp_path / "scene",
                          '<glue:Placement component="left" resource="head_node"/>'
                          '<glue:Placement component="right" resource="right_node"/>')
    here = subprocess.run(DSIM + ["run", str(folder), "--out", str(tmp_path / "here.csv"),
                                  "--quiet", "--stop", "1"],
                          cwd=ROOT, env=cluster["env"], capture_output=True, text=True,
                          timeout=300)
    there = subprocess.run(DSIM + ["run", str(folder), "--out", str(tmp_path / "there.csv"),
                                   "--stop", "1", "--backend", "ray", "--address",
                                   cluster["address"]],
                           cwd=ROOT, env=cluster["env"], capture_output=True, text=True,
                           timeout=300)
    assert here.returncode == 0 and there.returncode == 0, there.stderr
    assert there.stderr == "" and "ray backend" in there.stdout
    assert (tmp_path / "there.csv").read_bytes() == (tmp_path / "here.csv").read_bytes()
    stats = json.loads((tmp_path / "there.stats.json").read_text())
    nodes = nodes_with(cluster)
    assert nodes["head_node"] != nodes["right_node"]
    assert stats["components"]["left"]["worker"]["node"] == nodes["head_node"]
    assert stats["components"]["right"]["worker"]["node"] == nodes["right_node"]


def test_a_sweep_on_the_cluster_gives_the_points_of_a_serial_sweep(built, cluster, tmp_path):
    scene = built["ssp"] / "spring_mass_nonlinear.ssp"
    points = ["--step", "0.01,0.02", "--stop", "2"]
    serial = subprocess.run(DSIM + ["sweep", str(scene), *points, "--out",
                                    str(tmp_path / "serial")],
                            cwd=ROOT, env=cluster["env"], capture_output=True, text=True,
                            timeout=300)
    spread = subprocess.run(DSIM + ["sweep", str(scene), *points, "--out",
                                    str(tmp_path / "spread"), "--backend", "ray",
                                    "--address", cluster["address"]],
                            cwd=ROOT, env=cluster["env"], capture_output=True, text=True,
                            timeout=300)
    assert serial.returncode == 0 and spread.returncode == 0, spread.stderr
    for name in ("point_001.csv", "point_002.csv"):
        assert (tmp_path / "spread" / name).read_bytes() == \
            (tmp_path / "serial" / name).read_bytes()
    columns = (tmp_path / "spread" / "sweep.csv").read_text().splitlines()
    assert len(columns) == 3 and all(",completed,true," in row for row in columns[1:])


@contextmanager
def own_head(cpus: int = 1):
    """A one-node cluster of its own (a test that kills its head, or wants a node with
    more CPUs): its address, environment and node process."""
    folder = Path(tempfile.mkdtemp(prefix="dsimhead", dir="/tmp"))  # short: socket paths
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
           "RAY_USAGE_STATS_ENABLED": "0", "OMP_NUM_THREADS": "1"}
    head, port = start_head([f"--num-cpus={cpus}", "--include-dashboard=false",
                             f"--temp-dir={folder}", "--object-store-memory=80000000"],
                            env, folder)
    try:
        yield {"address": f"127.0.0.1:{port}", "env": env, "head": head}
    finally:
        stop_node(head)
        shutil.rmtree(folder, ignore_errors=True)


def nodes_of_components(stats_file: Path) -> dict[str, str]:
    """Component -> the Ray node id its worker ran on, as the statistics say."""
    stats = json.loads(stats_file.read_text())
    return {name: c["worker"]["node"] for name, c in stats["components"].items()}


def test_components_without_a_placement_each_run_on_a_node_of_their_own(built, cluster,
                                                                         tmp_path):
    """Two nodes, two components without a placement: in every run each on its own node
    (Ray's SPREAD alone put both on one node in 4 of 9 runs); and a component placed on
    the second node leaves the head to the other."""
    nodes = nodes_with(cluster)
    plain = built["ssp"] / "spring_mass_linear.ssp"
    placed = placed_scene(built, tmp_path / "scene",
                          '<glue:Placement component="left" resource="right_node"/>')
    for n, scene in enumerate([plain, plain, placed]):
        target = tmp_path / f"run{n}.csv"
        run = subprocess.run(DSIM + ["run", str(scene), "--stop", "0.05", "--quiet",
                                     "--backend", "ray", "--address", cluster["address"],
                                     "--out", str(target)],
                             cwd=ROOT, env=cluster["env"], capture_output=True, text=True,
                             timeout=300)
        assert run.returncode == 0 and run.stderr == "" and run.stdout == "", run.stderr
        where = nodes_of_components(target.with_suffix(".stats.json"))
        assert sorted(where.values()) == sorted(nodes.values()), (n, where, nodes)
    assert where == {"left": nodes["right_node"], "right": nodes["head_node"]}


#: a script's run of scene argv[2] on the cluster at argv[1]: which workers dsim started
#: ahead of it (ray_spares.ahead, waited for here), which ran its components, and what
#: is left after it (one run per process: Ray can end a process that shuts down its
#: second connection, docs/distributed.md)
AHEAD_SCRIPT = """
import json, sys
import ray
import dsim
from dsim.master.errors import InputError
from dsim.master.running.backends.ray import spares as ray_spares

started = []
first = ray_spares.ahead
def ahead(ray=None):
    count = first(ray)
    ray_spares.settle()
    started.extend(ray_spares.pids(sys.modules["ray"]))
    return count
ray_spares.ahead = ahead
try:
    result = dsim.simulate(sys.argv[2], stop=0.05, backend="ray", address=sys.argv[1])
    used = sorted({c["worker"]["pid"] for c in result.statistics["components"].values()})
except InputError:
    used = "refused"
print(json.dumps({"started": sorted(started), "used": used,
                  "after": [ray.is_initialized(), ray_spares.count()]}))
"""


def test_fewer_nodes_than_workers_to_spread_is_said_in_one_line(built, tmp_path):
    """One node of two CPUs: the two workers share it, and one line says so, naming five
    components at most; a run given the cluster's address joins it and starts its
    workers before it reads the scene (ray_cluster.connect_ahead), runs on them, and
    leaves the cluster as it found it, also when its scene is refused."""
    with own_head(cpus=2) as head:
        target = tmp_path / "run.csv"
        chain = tmp_path / "chain.csv"
        run, long = (subprocess.run(
            DSIM + ["run", str(built["ssp"] / scene), "--stop", "0.05", "--quiet",
                    "--backend", "ray", "--address", head["address"], "--out", str(out)],
            cwd=ROOT, env=head["env"], capture_output=True, text=True, timeout=300)
            for scene, out in (("spring_mass_linear.ssp", target), ("chain_10.ssp", chain)))
        scripts = [subprocess.run(
            [sys.executable, "-c", AHEAD_SCRIPT, head["address"], str(scene)],
            cwd=ROOT, env=head["env"], capture_output=True, text=True, timeout=300)
            for scene in (built["ssp"] / "chain_10.ssp", tmp_path / "missing.ssp")]
    said = []
    for script in scripts:
        assert script.returncode == 0, script.stderr
        said.append(json.loads(script.stdout.splitlines()[-1]))
    ran, refused = said
    assert len(ran["used"]) == 2 and ran["used"] == ran["started"], ran
    assert refused["used"] == "refused" and len(refused["started"]) == 2, refused
    assert ran["after"] == refused["after"] == [False, 0], said  # disconnected, no spare
    assert long.returncode == 0 and long.stdout == "", long.stderr
    [line] = long.stderr.splitlines()
    assert re.search(r"\(components 'm\d+', 'm\d+', 'm\d+', 'm\d+', 'm\d+' and 5 more "
                     r"share node", line), line
    assert run.returncode == 0 and run.stdout == "", run.stderr
    where = nodes_of_components(target.with_suffix(".stats.json"))
    assert len(set(where.values())) == 1
    [line] = run.stderr.splitlines()
    assert re.fullmatch(
        r"dsim: warning: placement: 2 workers of components without a placement, 1 node "
        r"with CPUs in the cluster: not one node each \(components 'left', 'right' share "
        rf"node [\d.]+, {where['left'][:12]}\)", line), line


# --- what survives what (docs/distributed.md) ---------------------------------------
def wait_for_cpus(address: str, count: float, env) -> None:
    """Until the cluster at ``address`` counts ``count`` CPUs: a node that says it is up
    (`ray start`'s "block forever") is known to the cluster's scheduler a moment later,
    and a sweep started before then keeps one point fewer in flight."""
    deadline = time.monotonic() + 60
    while True:
        said = subprocess.run([RAY, "status", f"--address={address}"], env=env, cwd=ROOT,
                              capture_output=True, text=True, timeout=60).stdout
        cpus = [float(n) for n in re.findall(r"/(\d+(?:\.\d+)?) CPU", said)]
        if cpus and max(cpus) >= count:
            return
        assert time.monotonic() < deadline, said
        time.sleep(0.5)


def processes_of(process: subprocess.Popen, name: str, program: bool = False) -> list[int]:
    """The processes named ``name`` (in their command line; with ``program``, the name
    of the program they run: a worker still starting names the raylet in its arguments,
    ``--raylet-name``) among those a node started."""
    from dsim.master.running.interrupts import descendants

    found = []
    for pid in descendants(process.pid):
        try:
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if (Path(argv[0].decode(errors="replace")).name == name if program
                else name.encode() in b" ".join(argv)):
            found.append(pid)
    return found


def wait_for_rows(target: Path, process: subprocess.Popen, size: int = 2000) -> None:
    """Until the run's CSV (under its temporary name) holds ``size`` bytes of rows."""
    partial = target.parent / f".{target.name}.partial"
    deadline = time.monotonic() + 120
    while not (partial.exists() and partial.stat().st_size > size):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)


def test_a_lost_node_does_not_end_the_run_its_component_goes_on_elsewhere(built, cluster,
                                                                        tmp_path):
    """A third node joins with a resource of its own; the component placed there is
    started again on a node that is left when the node goes down mid-run (its raylet
    and workers killed), from the last converged step: the CSV is the undisturbed
    run's, byte for byte."""
    spare = start_node([f"--address={cluster['address']}", "--num-cpus=1",
                        '--resources={"spare_node": 1}', "--object-store-memory=80000000"],
                       cluster["env"], tmp_path / "spare.log")
    try:
        folder = placed_scene(built, tmp_path / "scene",
                              '<glue:Placement component="right" resource="spare_node"/>')
        run = DSIM + ["run", str(folder), "--stop", "4", "--quiet", "--backend", "ray",
                      "--address", cluster["address"]]
        here = subprocess.run(DSIM + ["run", str(folder), "--stop", "4", "--quiet", "--out",
                                      str(tmp_path / "here.csv")],
                              cwd=ROOT, capture_output=True, text=True, timeout=300)
        assert here.returncode == 0, here.stderr
        target = tmp_path / "there.csv"
        process = subprocess.Popen(run + ["--out", str(target)], cwd=ROOT, env=cluster["env"],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        wait_for_rows(target, process)
        raylet = processes_of(spare, "raylet", program=True)
        assert len(raylet) == 1
        # the node goes down as a machine does: its raylet and its workers at once (a
        # worker whose raylet alone was killed answered calls for a while, and a short
        # run could end before it noticed: no loss to recover)
        from dsim.master.running.interrupts import descendants

        for pid in [*descendants(raylet[0]), raylet[0]]:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        out, err = process.communicate(timeout=300)
    finally:
        stop_node(spare)
    assert process.returncode == 0, err
    assert out == ""  # nothing of Ray's on stdout
    assert target.read_bytes() == (tmp_path / "here.csv").read_bytes()
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    losses = stats["lost_workers"]
    # one loss per worker that was on the node ("left" may have been spread there too)
    assert "right" in [c for loss in losses for c in loss["components"]], losses
    for loss in losses:
        assert loss["what"] == "lost node" and loss["recovered"], losses
        assert loss["message"].startswith("lost node ") and 0 < loss["time"] < 4
        assert 0 < loss["recovery_seconds"] < 60  # a node that is left, at once
        for name in loss["components"]:
            assert stats["components"][name]["worker"]["node"] != loss["node"]
    assert [loss.get("moved_from") for loss in losses if "right" in loss["components"]] \
        == ["spare_node"]


def test_a_lost_head_ends_the_run_within_seconds_with_everything_kept(built, tmp_path):
    """A head of its own (this test kills it): its GCS killed mid-run, dsim's own
    watchdog ends the run in seconds (Ray would wait a minute, then end the process
    without results): exit 1, the CSV and the statistics under their names, one line
    naming what was lost, nothing on stdout."""
    folder = Path(tempfile.mkdtemp(prefix="dsimhead", dir="/tmp"))  # short: socket paths
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
           "RAY_USAGE_STATS_ENABLED": "0", "OMP_NUM_THREADS": "1"}
    head, port = start_head(["--num-cpus=1", "--include-dashboard=false",
                             f"--temp-dir={folder}", "--object-store-memory=80000000"],
                            env, folder)
    target = tmp_path / "run.csv"
    try:
        process = subprocess.Popen(DSIM + ["run", str(built["ssp"] / "spring_mass_linear.ssp"),
                                           "--stop", "1000", "--backend", "ray", "--address",
                                           f"127.0.0.1:{port}", "--out", str(target), "--quiet"],
                                   cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
        wait_for_rows(target, process)
        [gcs] = processes_of(head, "gcs_server", program=True)
        os.kill(gcs, signal.SIGKILL)
        killed = time.monotonic()
        out, err = process.communicate(timeout=120)
        ended = time.monotonic() - killed
    finally:
        stop_node(head)
        shutil.rmtree(folder, ignore_errors=True)
    assert process.returncode == 1 and ended < 10 and out == "", err
    lines = err.strip().splitlines()
    assert len(lines) in (2, 3), lines
    # (the log is named by the pid of the process that stepped: dsim run's child)
    assert lines[2:] == [] or re.fullmatch(
        rf"dsim: what Ray's own processes said meanwhile is in /tmp/dsim-{os.getuid()}/"
        r"ray-\d+\.log", lines[2]), lines
    assert re.fullmatch(r"dsim: simulation failed: lost the Ray head \(its GCS at \S+ stopped "
                        r"answering\): no worker can be reached \(stopped at t = [\d.]+ s, step "
                        r"(\d+) of 100000\)", lines[0])
    steps = int(re.search(r"step (\d+) of", lines[0]).group(1))
    assert lines[1] == (f"dsim: the {steps} converged steps are in {target}, statistics in "
                        f"{target.with_suffix('.stats.json')}")
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert stats["status"] == "failed" and stats["steps"] == steps > 5
    assert len(target.read_text().splitlines()) == steps + 2  # header, start, the steps


def test_the_heads_raylet_lost_mid_run_leaves_a_failed_runs_files(built, tmp_path):
    """The head node's raylet killed (SIGKILL) while a run steps on it.  Either Ray ends
    its driver at once (the process that steps, with nothing said: seen with Ray 2.5x
    when the raylet went first), as the out-of-memory killer would, and dsim run's
    supervisor finishes its files; or the driver lives long enough for dsim's own watch
    of the head to end the run.  Both leave a failed run's files: every whole row under
    run.csv, statistics saying how and when, a line saying so, exit 1."""
    with own_head(cpus=2) as head:
        target = tmp_path / "run.csv"
        process = subprocess.Popen(
            DSIM + ["run", str(built["ssp"] / "spring_mass_nonlinear.ssp"), "--stop", "1000",
                    "--backend", "ray", "--address", head["address"], "--out", str(target),
                    "--quiet"], cwd=ROOT, env=head["env"], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True)
        wait_for_rows(target, process)
        [raylet] = processes_of(head["head"], "raylet", program=True)
        os.kill(raylet, signal.SIGKILL)
        out, err = process.communicate(timeout=120)
    assert process.returncode == 1 and out == "", err
    [failed] = [line for line in err.splitlines() if "simulation failed" in line]
    by_supervisor = re.fullmatch(
        r"dsim: simulation failed: the process stepping the run ended without finishing it "
        r"\((exit code \d+|killed by SIG\w+)\) at t = [\d.]+ s: its \d+ rows are kept in "
        r"\S+run.csv, statistics in \S+", failed)
    assert by_supervisor or re.match(r"dsim: simulation failed: lost the Ray head", failed), err
    rows = target.read_text().splitlines()
    assert len(rows) > 10 and all(r.count(",") == rows[0].count(",") for r in rows)
    stats = json.loads(target.with_suffix(".stats.json").read_text())
    assert stats["status"] == "failed" and stats["time_reached"] == float(
        rows[-1].split(",")[0])
    assert stats["rows" if by_supervisor else "steps"] == len(rows) - (1 if by_supervisor
                                                                        else 2)
    assert not list(tmp_path.glob(".*partial"))


def test_a_ray_run_whose_process_is_killed_goes_on_from_its_checkpoint(built, cluster,
                                                                      tmp_path):
    """A run on the cluster with checkpoints, its stepping process (the Ray driver)
    killed with SIGKILL at a random moment: dsim run's supervisor starts it again from
    the last checkpoint on the cluster; the CSV is the in-process run's never stopped,
    byte for byte, and the statistics but for where it ran and the restart."""
    from tests.support.checkpoints import killed_and_resumed, timeless

    (reference, expected), (out, statistics) = killed_and_resumed(
        built["ssp"] / "spring_mass_nonlinear.ssp", tmp_path, 30.0, 2.0, "--backend", "ray",
        "--address", cluster["address"], stepping=True, env=cluster["env"])
    assert out == reference
    assert statistics["backend"] == "ray" and len(statistics["restarts"]) == 1
    for stats in (statistics, expected):
        for key in ("backend", "restarts", "lost_workers"):
            stats.pop(key, None)
        stats["components"] = {name: (c["do_steps"], c["state_saves"], c["state_restores"])
                               for name, c in stats["components"].items()}
    assert timeless(statistics) == timeless(expected)


def sweep_losing_a_node(built, cluster, folder: Path, *options) -> tuple[list, dict]:
    """Three points on three nodes of one CPU each (the module's two and a third that
    joins for this sweep); the third node is lost while they run.  The command and the
    rows of sweep.csv by point number."""
    spare = start_node([f"--address={cluster['address']}", "--num-cpus=1",
                        "--object-store-memory=80000000"], cluster["env"], folder / "spare.log")
    wait_for_cpus(cluster["address"], 3, cluster["env"])
    out = folder / "sweep"
    command = DSIM + ["sweep", str(built["ssp"] / "spring_mass_linear.ssp"), "--stop", "60",
                      "--step", "0.01,0.011,0.012", "--backend", "ray", "--address",
                      cluster["address"], *options, "--out", str(out)]
    try:
        process = subprocess.Popen(command, cwd=ROOT, env=cluster["env"],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 180
        while not processes_of(spare, "_run_remote"):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.1)
        time.sleep(1.0)  # the point under way on it
        [raylet] = processes_of(spare, "raylet", program=True)
        os.kill(raylet, signal.SIGKILL)
        out_text, err = process.communicate(timeout=300)
    finally:
        stop_node(spare)
    assert process.returncode == 0, err
    assert "raylet" not in out_text and "Raylet" not in out_text  # nothing of Ray's
    with open(out / "sweep.csv") as table:
        return command, {row["point"]: row for row in csv.DictReader(table)}


def test_a_point_lost_with_its_node_runs_again_on_the_nodes_left(built, cluster, tmp_path):
    _, found = sweep_losing_a_node(built, cluster, tmp_path)
    assert [(row["status"], row["steps"]) for row in found.values()] == \
        [("completed", str(round(60 / float(row["step"])))) for row in found.values()], found


def test_a_point_lost_with_its_node_is_lost_not_failed_and_a_rerun_runs_it(built, cluster,
                                                                           tmp_path):
    """With --restarts 0 the point lost with its node is `lost` (not run again, not
    failed); the same command again runs it, and only it, on the nodes that are left."""
    command, found = sweep_losing_a_node(built, cluster, tmp_path, "--restarts", "0")
    lost = [k for k, row in found.items() if row["status"] == "lost"]
    assert len(lost) == 1, found
    assert found[lost[0]]["message"].startswith("lost with a node of the cluster 1 times")
    assert all(row["status"] == "completed" for k, row in found.items() if k not in lost)
    again = subprocess.run(command, cwd=ROOT, env=cluster["env"], capture_output=True,
                           text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert "2 of 3 points already finished" in again.stdout + again.stderr
    with open(command[-1] + "/sweep.csv") as table:
        final = list(csv.DictReader(table))
        assert [row["status"] for row in final] == ["completed"] * 3, [
            (row["status"], row["message"]) for row in final]


def test_a_lost_head_ends_a_sweep_within_seconds_its_lost_points_run_again(built, tmp_path):
    """A head of its own (one CPU: one point at a time); its GCS killed while the second
    point runs: the sweep's own watch ends it in seconds (Ray would wait a minute), exit
    1, one line naming what was lost; the first point kept, the second `lost`; the same
    sweep again (in-process: where it runs is not part of the sweep) runs only that one."""
    out = tmp_path / "sweep"
    sweep = DSIM + ["sweep", str(built["ssp"] / "spring_mass_linear.ssp"), "--stop", "1,60",
                    "--out", str(out)]
    with own_head(cpus=1) as head:
        process = subprocess.Popen(sweep + ["--backend", "ray", "--address", head["address"]],
                                   cwd=ROOT, env=head["env"], stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 180
        while not ((out / "point_001.csv").exists()
                   and processes_of(head["head"], "_run_remote")):
            assert process.poll() is None, process.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.1)
        [gcs] = processes_of(head["head"], "gcs_server", program=True)
        os.kill(gcs, signal.SIGKILL)
        killed = time.monotonic()
        out_text, err = process.communicate(timeout=120)
        ended = time.monotonic() - killed
    assert process.returncode == 1 and ended < 10 and out_text == "", err
    assert re.fullmatch(r"point 1/2: stop=1: completed, error \S+, [\d.]+ s",
                        err.splitlines()[0]), err
    assert err.splitlines()[1] == "point 2/2: stop=60: lost, 0.00 s", err
    lines = err.splitlines()[2:]
    assert len(lines) in (1, 2), err  # what was lost; where Ray's words are, if it said any
    assert re.fullmatch(r"dsim: sweep failed: lost the Ray head \(its GCS at \S+ stopped "
                        r"answering\): the points under way are lost \(2; a rerun of the "
                        r"sweep into the same folder runs them and those not started\), the "
                        rf"finished points are kept in {re.escape(str(out))}", lines[0]), err
    assert lines[1:] in ([], [f"dsim: what Ray's own processes said meanwhile is in "
                              f"/tmp/dsim-{os.getuid()}/ray-{process.pid}.log"]), err
    with open(out / "sweep.csv") as table:
        found = [(row["point"], row["status"]) for row in csv.DictReader(table)]
    assert found == [("1", "completed"), ("2", "lost")]
    again = subprocess.run(sweep, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert "1 of 2 points already finished" in again.stderr
    with open(out / "sweep.csv") as table:
        assert [(row["point"], row["status"], row["steps"]) for row in csv.DictReader(table)] \
            == [("1", "completed", "100"), ("2", "completed", "6000")]


#: what a script on the cluster at argv[1] finds of the spares commands left there
#: (ray_pool.py): {name: process id}; with argv[2] == "impostors" it first ends them
#: and leaves in their place two actors that are no spare of dsim's under names of
#: their form (one answers a claim with a string, one raises), and prints theirs; with
#: argv[2] == "end" it ends the actors named after it first
SPARES_SCRIPT = """
import json, os, sys, uuid
import ray
from dsim.master.running.backends.ray import pool as ray_pool

ray.init(address=sys.argv[1], logging_level="ERROR", log_to_driver=False)
space = ray_pool.namespace()
found = {name: ray.get(ray.get_actor(name, namespace=space).ready.remote(), timeout=60)
         for name, _ in ray_pool._listed(ray)}
if sys.argv[2:] == ["impostors"]:
    @ray.remote
    class Impostor:
        def __init__(self, answer):
            self.answer = answer
        def ready(self):
            return os.getpid()
        def claim(self, job):
            if self.answer == "raise":
                raise RuntimeError("no")
            return self.answer
    kinds = {name.split("-")[1] for name in found}
    for name in found:
        ray.kill(ray.get_actor(name, namespace=space))
    found = {}
    for answer in ("yes", "raise"):
        for kind in kinds:
            name = f"{ray_pool.build()}-{kind}-{uuid.uuid4().hex[:12]}"
            actor = Impostor.options(name=name, namespace=space, lifetime="detached",
                                     num_cpus=0).remote(answer)
            found[name] = ray.get(actor.ready.remote(), timeout=60)
elif sys.argv[2:3] == ["end"]:
    for name in sys.argv[3:]:
        ray.kill(ray.get_actor(name, namespace=space))
        found.pop(name)
print(json.dumps(found))
"""


def spares_of(head, *action) -> dict[str, int]:
    """The spares left in ``head``'s cluster: name -> process id (SPARES_SCRIPT)."""
    found = subprocess.run([sys.executable, "-c", SPARES_SCRIPT, head["address"], *action],
                           cwd=ROOT, env=head["env"], capture_output=True, text=True,
                           timeout=120)
    assert found.returncode == 0, found.stderr
    return json.loads(found.stdout.splitlines()[-1])


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_commands_on_a_cluster_take_the_spares_the_command_before_left(built, tmp_path):
    """Each `dsim run --address` leaves as many fresh workers in the cluster as it used
    (ray_pool.py), and the next command runs on them, its numbers unchanged to the
    byte; two commands at once never share a worker; a refused scene gives back what
    it claimed; actors that are no spare of
    dsim's under a spare's name are passed over, not used and not ended; a command
    killed outright takes its workers with it within seconds; a spare no command takes
    ends after DSIM_RAY_SPARE_SECONDS (DSIM_RAY_SPARES=0, which leaves none, is
    tests/distributed/test_ray_spares.py's)."""
    scene = str(built["ssp"] / "chain_10.ssp")

    def command(name, head, *extra, env=None, stop="0.05"):
        out = tmp_path / f"{name}.csv"
        run = subprocess.run(DSIM + ["run", scene, "--stop", stop, "--quiet", "--backend",
                                     "ray", "--address", head["address"], "--out",
                                     str(out), *extra],
                             cwd=ROOT, env={**head["env"], **(env or {})},
                             capture_output=True, text=True, timeout=300)
        stats = json.loads(out.with_suffix(".stats.json").read_text()) \
            if run.returncode == 0 else {}
        used = {c["worker"]["pid"] for c in stats.get("components", {}).values()}
        how = {c["worker"]["started"] for c in stats.get("components", {}).values()}
        return run, out, (used, how)

    with own_head(cpus=2) as head:
        first, first_out, (first_used, how) = command("first", head)
        assert first.returncode == 0, first.stderr
        assert how == {"ahead"}  # no spare there yet: started before its scene was read
        left = spares_of(head)
        assert len(left) == 2 and not set(left.values()) & first_used, (left, first_used)
        assert not any(alive(pid) for pid in first_used)  # the run's own are gone

        refused = subprocess.run(DSIM + ["run", str(tmp_path / "missing.ssp"), "--backend",
                                         "ray", "--address", head["address"]],
                                 cwd=ROOT, env=head["env"], capture_output=True, text=True,
                                 timeout=300)
        assert refused.returncode == 2, refused.stderr
        assert spares_of(head) == left  # claimed, then given back

        second, second_out, (second_used, how) = command("second", head)
        assert second.returncode == 0, second.stderr
        assert second_used == set(left.values())  # taken, not started anew
        assert how == {"cluster spare"}  # and the statistics say so
        assert second_out.read_bytes() == first_out.read_bytes()

        # two commands at once, two spares there: never a worker for both
        pair = [subprocess.Popen(DSIM + ["run", scene, "--stop", "0.05", "--quiet",
                                         "--backend", "ray", "--address", head["address"],
                                         "--out", str(tmp_path / f"pair{n}.csv")],
                                 cwd=ROOT, env=head["env"], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True) for n in range(2)]
        for process in pair:
            assert process.wait(300) == 0, process.communicate()[1]
        used = [{c["worker"]["pid"] for c in json.loads(
            (tmp_path / f"pair{n}.stats.json").read_text())["components"].values()}
            for n in range(2)]
        assert len(used[0]) == len(used[1]) == 2 and not used[0] & used[1], used
        for n in range(2):
            assert (tmp_path / f"pair{n}.csv").read_bytes() == first_out.read_bytes()
        impostors = spares_of(head, "impostors")
        assert len(impostors) == 2

        third, third_out, (third_used, _) = command("third", head)
        assert third.returncode == 0, third.stderr
        assert third_out.read_bytes() == first_out.read_bytes()
        assert not third_used & set(impostors.values()), (third_used, impostors)
        after = spares_of(head, "end", *impostors)  # untouched until then
        assert len(after) == 2 and not set(after.values()) & third_used, after

        # killed outright: its run cannot end its workers; they see its job end
        long = subprocess.Popen(DSIM + ["run", scene, "--stop", "50", "--quiet",
                                        "--backend", "ray", "--address", head["address"],
                                        "--out", str(tmp_path / "killed.csv")],
                                cwd=ROOT, env=head["env"], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        try:
            wait_for_rows(tmp_path / "killed.csv", long)
            workers = processes_of(head["head"], "ray::Host")
        finally:
            long.kill()
            long.wait()
        deadline = time.monotonic() + 30
        while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert sorted(workers) == sorted(after.values()), (workers, after)  # its own
        assert not any(alive(pid) for pid in workers), workers

        waiting, _, _ = command("waiting", head, env={"DSIM_RAY_SPARE_SECONDS": "8"})
        assert waiting.returncode == 0, waiting.stderr
        short = spares_of(head)
        assert len(short) == 2
        deadline = time.monotonic() + 30
        while any(alive(pid) for pid in short.values()) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not any(alive(pid) for pid in short.values()) and spares_of(head) == {}

