"""A scenario given with a run in dsim serve (docs/serve.md, docs/scenarios.md): the
form's text or the JSON API's ``scenario``, checked against the stored scene before
anything is queued, written into the run's folder, and giving ``dsim run --scenario``'s
bytes; refused in one line where the file would be."""
from __future__ import annotations

import html
import json

import dsim
from tests.support.serve_fixtures import server, wait_run  # noqa: F401

#: a load on the free port of spring_mass_linear inside a step of 0.01 s, at
#: 0.505 s, and the joint made stiffer at 0.3 s
SCENARIO = {"events": [
    {"time": 0.3, "model": "j1", "variable": "k0", "action": "override", "value": 400.0},
    {"time": 0.505, "model": "right", "variable": "P.f_x", "action": "override", "value": 5.0}]}


def test_a_run_with_a_scenario_from_the_form_gives_dsim_run_s_bytes(server, tmp_path):
    client, store, scene_id = server
    page = client.get(f"/scenes/{scene_id}").text
    assert 'name="scenario"' in page and 'name="events"' in page
    text = json.dumps(SCENARIO)
    answer = client.post(f"/scenes/{scene_id}/runs", follow_redirects=False, data={
        "stop": "1", "step": "0.01", "signal": "right.x[2]", "scenario": text,
        "events": "exact"})
    assert answer.status_code == 303, answer.text
    run = wait_run(client, int(answer.headers["location"].rsplit("/", 1)[1]))
    assert run["status"] == "completed", run
    folder = store.run_folder(run["id"])
    assert (folder / "scenario.json").read_text() == text
    scene = client.get(f"/api/scenes/{scene_id}").json()
    (tmp_path / "s.json").write_text(text)
    expected = dsim.simulate(store.blob_path(scene["sha256"]), stop=1.0, step=0.01,
                             out=tmp_path / "e.csv", scenario=tmp_path / "s.json",
                             events="exact")
    assert (folder / "results.csv").read_bytes() == (tmp_path / "e.csv").read_bytes()
    applied = run["statistics"]["scenario"]["applied"]
    assert [(a["time"], a["target"]) for a in applied] == [(0.3, "j1.k0"),
                                                          (0.505, "right.P.f_x")]
    assert expected.statistics["scenario"]["applied"] == applied
    status = html.unescape(client.get(f"/runs/{run['id']}").text)
    assert "--scenario scenario.json --events exact" in status


def test_the_api_takes_a_scenario_and_refuses_a_bad_one_in_one_line_each(server):
    client, store, scene_id = server
    runs = len(store.all("SELECT id FROM runs"))

    def launched(**body):
        return client.post(f"/api/scenes/{scene_id}/runs",
                           json={"settings": {"stop": 1}, **body})

    yaml = "events:\n  - time: 0.3\n    model: j1\n    variable: k0\n    action: override\n" \
           "    value: 400.0\n"
    answer = launched(scenario=yaml)
    assert answer.status_code == 200, answer.text
    run = wait_run(client, answer.json()["id"])
    assert run["status"] == "completed" and run["settings"]["scenario"]["format"] == "yml"
    for body, said in (
            (dict(scenario=json.dumps({"events": [{"time": 0.3, "model": "rigth",
                                                   "variable": "m[1]", "action": "override",
                                                   "value": 1.0}]})),
             "the scene has no component 'rigth' (closest: right"),
            (dict(scenario='{"events": [{"time": 2.5, "model": "right", "variable": "P.f_x", '
                           '"action": "bias", "value": 1.0}]}', events="point"),
             "is at or after the stop time 1 s"),
            (dict(scenario="{not json"), "scenario line 1: malformed JSON"),
            (dict(scenario="<!DOCTYPE x [<!ENTITY e SYSTEM 'file:///etc/passwd'>]><x/>"),
             "document type"),
            (dict(scenario=json.dumps(SCENARIO), events="soon"),
             "events 'soon' is not one of: point, exact"),
            (dict(events="exact"), "give a scenario with it"),
            (dict(scenario="x" * (256 * 1024 + 1)), "more than the 262144 a run takes")):
        answer = launched(**body)
        assert answer.status_code == 400, (body, answer.text)
        problems = answer.json()["problems"]
        assert len(problems) == 1 and said in problems[0], (said, problems)
    assert len(store.all("SELECT id FROM runs")) == runs + 1  # only the good one queued


def test_a_sweep_with_a_scenario_gives_dsim_sweep_s_points(server, tmp_path):
    """The sweep form's scenario: every point runs with it (the joint stiffened at
    0.3 s), the sweep's command says --scenario, and that command gives the same KPIs."""
    import csv

    from dsim.master.tools.cli import main as dsim_main

    client, store, scene_id = server
    text = json.dumps({"events": [SCENARIO["events"][0]]})
    answer = client.post(f"/scenes/{scene_id}/sweeps", follow_redirects=False, data={
        "step": "0.02, 0.01", "kpis": "max(right.x[2])", "stop": "0.6", "scenario": text})
    assert answer.status_code == 303, answer.text
    run_id = int(answer.headers["location"].rsplit("/", 1)[1])
    assert wait_run(client, run_id)["status"] == "completed"
    folder = store.run_folder(run_id)
    assert (folder / "scenario.json").read_text() == text
    status = html.unescape(client.get(f"/runs/{run_id}").text)
    assert "--scenario scenario.json" in status
    (tmp_path / "scenario.json").write_text(text)
    scene = store.blob_path(client.get(f"/api/scenes/{scene_id}").json()["sha256"])
    assert dsim_main(["sweep", str(scene), "--step", "0.02,0.01", "--kpi", "max(right.x[2])",
                      "--stop", "0.6", "--scenario", str(tmp_path / "scenario.json"),
                      "--out", str(tmp_path / "again")]) == 0

    def kpis(where):
        with open(where / "sweep.csv", newline="") as file:
            return sorted((r["step"], r["max(right.x[2])"]) for r in csv.DictReader(file))
    assert kpis(folder) == kpis(tmp_path / "again")
    plain = client.post(f"/scenes/{scene_id}/sweeps", follow_redirects=False, data={
        "step": "0.02, 0.01", "kpis": "max(right.x[2])", "stop": "0.6"})
    plain_id = int(plain.headers["location"].rsplit("/", 1)[1])
    assert wait_run(client, plain_id)["status"] == "completed"
    assert kpis(store.run_folder(plain_id)) != kpis(folder)  # the scenario acted
