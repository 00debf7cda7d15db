"""Shared fixtures: the FMUs and scene archives are built once per session
(skipped when up to date), so `pytest` alone works on a fresh checkout."""
import pytest

from tests.support.paths import ROOT


@pytest.fixture(scope="session")
def built():
    """Paths of build/fmus and build/ssp after building what is out of date."""
    from dsim.build_fmus.build import build_fmus, pack_scenes

    build_fmus(log=lambda message: None)
    pack_scenes(log=lambda message: None)
    return {"fmus": ROOT / "build" / "fmus", "ssp": ROOT / "build" / "ssp"}


@pytest.fixture(scope="session")
def block_fmus(tmp_path_factory):
    """The plain-C block FMU (tests/support/third_party/block.c) compiled with gcc, with and
    without state saving."""
    from tests.support.third_party.build import c_fmu

    folder = tmp_path_factory.mktemp("block")
    return {"state": c_fmu(folder, "block"),
            "nostate": c_fmu(folder, "block_nostate", can_save_state=False)}


@pytest.fixture(scope="session")
def ender(tmp_path_factory):
    """The C FMU that ends the simulation itself (tests/support/ender.py), compiled with
    gcc against fmpy's FMI 2.0 headers."""
    from tests.support.ender import build_ender

    return build_ender(tmp_path_factory.mktemp("ender"))


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


def _cpu_seconds() -> float:
    """CPU seconds of this process and of the processes it started and waited for."""
    import resource

    return sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
               for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    item._dsim_cpu_start = _cpu_seconds()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """The CPU seconds of each test, set-up and tear-down included, as the property
    ``cpu`` in the JUnit XML `make test` writes (tests/support/timing.py sums it): on
    two cores the suite is bound by the CPU, so what a test costs the others is its CPU,
    not its wall time.  Processes a test leaves running (a Ray node) are not counted."""
    outcome = yield
    start = getattr(item, "_dsim_cpu_start", None)
    if call.when == "teardown" and start is not None:
        outcome.get_result().user_properties.append(
            ("cpu", round(_cpu_seconds() - start, 3)))


def pytest_sessionfinish(session, exitstatus):
    session.config._dsim_exit_status = exitstatus


# ---------------------------------------------------------------------------------------
# The test tiers (README, "Tests"; docs/ci.md): markers registered in pyproject.toml,
# assigned here, centrally, so that no test module needs to carry them.
#
#   make quick  ->  -m "not (wheel or kernels or ray or browser or fuzz or slow)"
#   make test   ->  everything: the `ray` and `wheel` tests in one pytest process, the
#                   others in a second one beside it (the Makefile says why that is safe)
#
# A test gets the markers of its module (MODULE_MARKERS), `ray` if it uses the
# session's Ray instance (the ray_local fixture), and those of its entry in NODE_MARKERS.

#: a test file, or a folder (ending in /), relative to the repository -> markers of
#: every test in it
MODULE_MARKERS = {
    "tests/tools/test_wheel.py": ("wheel",),
    "tests/checks/test_kernels.py": ("kernels",),
    "tests/distributed/test_ray_backend.py": ("ray",),
    "tests/distributed/test_ray_cluster.py": ("ray",),
    "tests/distributed/test_ray_sweep.py": ("ray",),
    "tests/reading/test_ssp_fuzz.py": ("fuzz",),
    "tests/serve/": ("serve",),
    "tests/serve/test_serve_browser.py": ("browser",),
}

#: "tests/FOLDER/FILE.py::FUNCTION" (every parametrization of it) or a full node id ->
#: markers.  Kept small: the tests that start Ray without the ray_local fixture (a dsim
#: process run with --isolate or --backend ray), the kernel study of test_bands.py, and
#: `slow`: the other tests that took over ~3 s in a full run on two cores (`--durations`,
#: docs/ci.md).  A new test over ~3 s belongs here, or in one of the modules above.
NODE_MARKERS = {
    # Ray without the ray_local fixture
    "tests/running/test_hung_fmu.py::test_a_second_signal_ends_a_run_stuck_in_an_fmu_at_once_with_every_row[isolated-SIGINT]": ("ray",),
    "tests/running/test_hung_fmu.py::test_a_second_signal_ends_a_run_stuck_in_an_fmu_at_once_with_every_row[isolated-SIGTERM]": ("ray",),
    "tests/running/test_hung_fmu.py::test_a_second_signal_ends_a_run_stuck_in_an_fmu_at_once_with_every_row[ray-SIGTERM]": ("ray",),
    "tests/serve/test_serve_api.py::test_a_run_on_the_isolated_backend_gives_the_in_process_numbers": ("ray",),
    "tests/tools/test_files_security.py::test_an_address_answers_the_same_whatever_the_port_state": ("ray",),
    # OpenBLAS kernel studies (each run again under every kernel this CPU has)
    "tests/checks/test_bands.py::test_kernel_study_measures_noise_and_a_result_beyond_it_regresses": ("kernels",),
    # slow: 5 to 20 s each
    "tests/checks/test_validate_and_regress.py::test_every_shipped_scene_matches_its_baseline": ("slow",),
    "tests/house/test_imports.py::test_every_module_imports_alone_in_a_fresh_interpreter": ("slow",),
    "tests/running/test_step_control.py::test_an_fmu_that_cannot_go_back_in_co_simulation_runs_its_model_exchange": ("slow",),
    "tests/running/test_coupling_error.py::test_a_strong_run_close_to_its_closed_form_does_not_warn": ("slow",),
    "tests/tools/test_error_paths.py::test_an_error_path_ends_with_its_exit_code_and_one_line_never_a_signal": ("slow",),
    "tests/sweeps/test_sweep.py::test_a_sweep_over_fidelity_sets_ranks_them_against_the_finest": ("slow",),
    "tests/running/test_stability.py::test_fixed_joints_pass_the_four_bar_singular_points_on_the_penalized_measure": ("slow",),
    "tests/fmus/test_fmi_kinds_fmus.py::test_memory_safety": ("slow",),
    "tests/running/test_pythonfmu_exit.py::test_a_process_that_ran_a_pythonfmu_fmu_exits_without_a_second_release": ("slow",),
    "tests/sweeps/test_doe.py::test_a_terminated_serial_sweep_finishes_on_the_same_command": ("slow",),
    # slow: over 3 s on the AMD EPYC machines (make quick --durations, 2026-11-28)
    "tests/checks/test_validate_and_regress.py::test_regress_update_writes_the_missing_baselines": ("slow",),
    "tests/fmus/test_linkage_core.py::test_glued_parts_match_whole_crank_slider": ("slow",),
    "tests/fmus/test_fmus_alone.py::test_a_built_fmu_validates_and_simulates_alone_with_its_defaults": ("slow",),
    "tests/fmus/test_frame_scenes.py::test_fmu_validates_and_runs_alone": ("slow",),
    "tests/fmus/test_linkage_scenes.py::test_four_bar_fixed_passes_the_singular_point_on_the_displacement_measure": ("slow",),
    "tests/fmus/test_four_post.py::test_generic_fmu_from_a_user_mesh_file": ("slow",),
    "tests/serve/test_serve_api.py::test_a_sweeps_command_line_is_the_dsim_sweep_that_makes_it": ("slow",),
    "tests/running/test_stability.py::test_a_step_newton_cannot_finish_is_cut_and_the_run_passes": ("slow",),
    "tests/running/test_fmi_kinds.py::test_model_exchange_without_fmu_state_rolls_back_its_continuous_states": ("slow",),
    "tests/fmus/test_linkage_scenes.py::test_crank_slider_flexible_matches_monolithic": ("slow",),
    "tests/reading/test_units.py::test_every_built_fmu_declares_si_units_and_validates": ("slow",),
    "tests/fmus/test_fmi_kinds_fmus.py::test_fmpy_validate_command_agrees": ("slow",),
    "tests/running/test_roundoff.py::test_a_failed_reference_does_not_stop_the_build": ("slow",),
    "tests/serve/test_serve_processes.py::test_a_crashing_fmu_ends_its_run_never_the_server": ("slow",),
    "tests/fmus/test_linkage_scenes.py::test_crank_slider_rigid_matches_monolithic": ("slow",),
    "tests/fmus/test_linkage_scenes.py::test_four_bar_fixed_fails_cleanly_at_the_singular_point_under_the_trapezoidal_rule": ("slow",),
    "tests/sweeps/test_doe.py::test_salib_designs_give_sobol_and_morris_indices_that_rank_as_the_physics": ("slow",),
    "tests/serve/test_serve_api.py::test_a_stored_scene_fills_the_form_and_saves_as_a_new_one_with_its_numbers": ("slow",),
    "tests/fmus/test_elastic_core.py::test_solid_hex_cantilever_with_rigid_end": ("slow",),
    "tests/serve/test_serve_api.py::test_a_run_takes_model_parameters_from_the_scene_form": ("slow",),
    "tests/serve/test_serve_api.py::test_a_parameter_set_makes_a_new_scene_and_compare_finds_where_runs_differ": ("slow",),
    "tests/serve/test_serve_api.py::test_a_page_opened_on_a_long_run_gets_its_history_thinned": ("slow",),
    "tests/running/test_fmi_kinds.py::test_strongly_coupled_connections_beat_the_exchange_tenfold": ("slow",),
    "tests/house/test_names_defined.py::test_no_python_file_of_the_project_uses_an_undefined_name": ("slow",),
    "tests/fmus/test_linkage_core.py::test_index3_has_parasitic_force_oscillation": ("slow",),
    "tests/fmus/test_linkage_core.py::test_crank_slider_kinematics_closed_form": ("slow",),
    "tests/fmus/test_four_post.py::test_rigid_set_runs_the_rigid_plate": ("slow",),
    "tests/tools/test_files_security.py::test_an_fmu_source_outside_the_scene_is_refused": ("slow",),
    "tests/fmus/test_flexible_mechanism.py::test_stiff_coupler_reproduces_the_rigid_linkage": ("slow",),
    # slow: 3 to 4 s each (out of `make quick`, to keep it well under 3 minutes)
    "tests/running/test_hung_fmu.py::test_the_first_signal_ends_a_run_stuck_in_an_fmu_after_the_grace_period": ("slow",),
    "tests/running/test_hung_fmu.py::test_the_first_signal_ends_a_set_up_stuck_in_an_fmu_after_the_grace_period": ("slow",),
    "tests/running/test_stability.py::test_undamped_energy_drifts_no_more_than_the_twins": ("slow",),
    "tests/tools/test_files_security.py::test_a_scene_of_many_components_is_checked_in_linear_time": ("slow",),
    "tests/fmus/test_flexible_link_core.py::test_glued_crank_slider_with_flexible_coupler": ("slow",),
    "tests/fmus/test_linkage_scenes.py::test_penalized_bounds_the_drift_that_acceleration_only_gluing_lets_grow": ("slow",),
    "tests/serve/test_serve_api.py::test_a_parameter_sweep_from_the_form_shows_kpis_sensitivity_and_plots": ("slow",),
    "tests/serve/test_serve_api.py::test_a_third_party_fmu_is_glued_through_a_port_map_made_in_the_form": ("slow",),
    "tests/serve/test_serve_processes.py::test_runs_in_flight_when_the_server_ends_show_as_interrupted": ("slow",),
    "tests/serve/test_serve_security.py::test_parallel_uploads_of_one_fmu_are_one_model": ("slow",),
    "tests/checks/test_validate_and_regress.py::test_regress_finds_a_regression_and_reports_it": ("slow",),
    "tests/running/test_scaling.py::test_ten_thousand_components_validate_with_the_right_findings": ("slow",),
    "tests/running/test_scaling.py::test_validation_grows_linearly_with_the_components": ("slow",),
    # slow: checkpoints, the supervisor and scenarios, 4 to 9 s each (2026-11-29)
    "tests/running/test_checkpoints.py::test_a_run_killed_with_sigkill_at_a_random_point_resumes_to_the_same_bytes": ("slow",),
    "tests/running/test_checkpoints.py::test_an_interrupted_run_leaves_a_checkpoint_where_it_stopped": ("slow",),
    "tests/running/test_checkpoints.py::test_a_model_exchange_run_killed_with_sigkill_resumes_to_the_same_bytes": ("slow",),
    "tests/tools/test_supervisor.py::test_with_checkpoints_the_run_goes_on_by_itself": ("slow",),
    "tests/running/test_scenario_joints.py::test_a_run_resumed_after_a_law_change_goes_on_with_the_changed_law": ("slow",),
    "tests/running/test_scenario_joints.py::test_the_penalized_measures_coefficients_set_by_a_scenario_weigh_as_set_for_the_run": ("slow",),
    "tests/serve/test_serve_scenario.py::test_a_sweep_with_a_scenario_gives_dsim_sweep_s_points": ("slow",),
    "tests/serve/test_serve_scenario.py::test_the_api_takes_a_scenario_and_refuses_a_bad_one_in_one_line_each": ("slow",),
}


def _defined(path) -> set[str]:
    """The test functions a file defines: "name" and "Class::name"."""
    import ast

    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.ClassDef):
            names.update(f"{node.name}::{n.name}" for n in node.body
                         if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)))
    return names


def _stale_marker_keys(root, items) -> list[str]:
    """The keys of MODULE_MARKERS and NODE_MARKERS that name no test: a file or folder
    that is not there, a function its file does not define, or a parametrization of a
    collected function that was not collected.  Checked in every run, also one of a
    single file, so that a test moved or renamed cannot silently lose its markers."""
    stale = []
    for key in MODULE_MARKERS:
        folder = key.endswith("/")
        if not ((root / key).is_dir() if folder else (root / key).is_file()):
            stale.append(f"MODULE_MARKERS[{key!r}]: no such {'folder' if folder else 'file'}")
    ids = {item.nodeid for item in items}
    functions = {item.nodeid.split("[")[0] for item in items}
    defined = {}
    for key in NODE_MARKERS:
        file, _, function = key.split("[")[0].partition("::")
        if not (root / file).is_file():
            stale.append(f"NODE_MARKERS[{key!r}]: no such file")
            continue
        if file not in defined:
            defined[file] = _defined(root / file)
        if function not in defined[file]:
            stale.append(f"NODE_MARKERS[{key!r}]: {file} defines no {function}")
        elif "[" in key and key.split("[")[0] in functions and key not in ids:
            stale.append(f"NODE_MARKERS[{key!r}]: no such parametrization was collected")
    return stale


@pytest.hookimpl(tryfirst=True)  # before -m deselects by them
def pytest_collection_modifyitems(config, items):
    stale = _stale_marker_keys(config.rootpath, items)
    if stale:  # (pytest.exit: a UsageError's message is printed after pytest_unconfigure)
        pytest.exit("tests/conftest.py: markers that name no test (a test moved or renamed? "
                    "update the key):\n  " + "\n  ".join(stale),
                    returncode=pytest.ExitCode.USAGE_ERROR)
    for item in items:
        file = item.nodeid.split("::")[0]
        names = set()
        for key, markers in MODULE_MARKERS.items():
            if file == key or (key.endswith("/") and file.startswith(key)):
                names.update(markers)
        if "ray_local" in item.fixturenames:
            names.add("ray")
        names.update(NODE_MARKERS.get(item.nodeid.split("[")[0], ()))
        names.update(NODE_MARKERS.get(item.nodeid, ()))
        for name in sorted(names):
            item.add_marker(name)
    # the modules whose Ray tests start Ray their own way (a cluster of `ray start`
    # nodes, a dsim process with --isolate) first: the session's local instance
    # (ray_local) starts at its first test and would otherwise idle through them, at
    # about 15 % of a core (gcs_server, raylet, log monitor, measured with ps)
    uses_local = {item.nodeid.split("::")[0] for item in items
                  if "ray_local" in item.fixturenames}
    own = {item.nodeid.split("::")[0] for item in items
           if item.get_closest_marker("ray")} - uses_local
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in own)  # stable
