"""The spring-mass physics core against closed-form answers (no FMI)."""
import math

import numpy as np
import pytest

from dsim.fmus.spring_mass.core import ChainParameters, SpringMassChain


def oscillator(m=2.0, k=50.0, x0=0.1, n=1):
    params = ChainParameters(n=n)
    params.m[0], params.k_ground[0], params.x0[0] = m, k, x0
    chain = SpringMassChain(params)
    chain.initialize(0.0)
    return chain


def run(chain, step, stop):
    count = round(stop / step)
    x = [chain.x[0]]
    for i in range(count):
        chain.step(i * step, step)
        x.append(chain.x[0])
    return np.arange(count + 1) * step, np.array(x)


def test_trapezoidal_oscillator_matches_its_discrete_closed_form():
    """The trapezoidal rule keeps the amplitude and shifts the frequency to
    w_h = (2/h) atan(w h / 2): x_n = x0 cos(w_h t_n) exactly."""
    m, k, x0, h = 2.0, 50.0, 0.1, 0.01
    w = math.sqrt(k / m)
    times, x = run(oscillator(m, k, x0), h, 5.0)
    w_h = 2.0 / h * math.atan(w * h / 2.0)
    assert np.max(np.abs(x - x0 * np.cos(w_h * times))) < 1e-13


def test_oscillator_converges_to_exact_solution_at_second_order():
    m, k, x0 = 2.0, 50.0, 0.1
    w = math.sqrt(k / m)
    errors, steps = [], [0.02, 0.01, 0.005, 0.0025]
    for h in steps:
        times, x = run(oscillator(m, k, x0), h, 2.0)
        errors.append(np.max(np.abs(x - x0 * np.cos(w * times))))
    order = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert 1.95 < order < 2.05
    assert errors[-1] < 2e-4 * x0


def test_static_load_settles_on_nonlinear_spring():
    """A damped mass under F on a spring (k0 + k1|x|) x settles where the
    spring carries F: k1 x^2 + k0 x - F = 0."""
    params = ChainParameters(n=1)
    params.m[0], params.k_ground[0], params.k1_ground[0] = 1.0, 100.0, 1000.0
    params.c_ground[0], params.F0[0] = 30.0, 10.0
    chain = SpringMassChain(params)
    chain.initialize(0.0)
    times, x = run(chain, 0.01, 20.0)
    expected = (-100.0 + math.sqrt(100.0 ** 2 + 4 * 1000.0 * 10.0)) / (2 * 1000.0)
    assert x[-1] == pytest.approx(expected, rel=1e-9)
    assert chain.newton_iterations >= 1


def test_state_restore_repeats_a_step_bit_for_bit():
    params = ChainParameters(n=2)
    params.m[:2] = 10.0
    params.k[0], params.k1[0], params.c1[0], params.F0[1] = 100.0, 1000.0, 1.4e4, 10.0
    chain = SpringMassChain(params)
    chain.initialize(0.0)
    for i in range(30):
        chain.step(i * 0.01, 0.01)
    saved = chain.get_state()
    chain.set_interface_forces(np.array([0.5, -0.2]))
    chain.step(0.3, 0.01)
    first = (chain.x.copy(), chain.v.copy(), chain.a.copy())
    chain.step(0.31, 0.01)
    chain.set_state(saved)
    chain.set_interface_forces(np.array([0.5, -0.2]))
    chain.step(0.3, 0.01)
    assert all(np.array_equal(a, b) for a, b in zip(first, (chain.x, chain.v, chain.a)))


def test_bad_parameters_are_named():
    with pytest.raises(ValueError, match="port Q on mass 3"):
        SpringMassChain(ChainParameters(n=2, port_Q=3))


def _post(k1=0.0):
    """A stiff, critically damped post (1 kg, 1e8 N/m) on a 0.05 m half-sine bump of 0.1 s
    starting at t = 0.2 s."""
    params = ChainParameters(n=1)
    params.m[0], params.k_ground[0], params.c_ground[0] = 1.0, 1e8, 2e4
    params.k1_ground[0] = k1
    params.bump[0], params.bump_start[0], params.bump_duration[0] = 0.05, 0.2, 0.1
    return SpringMassChain(params)


def test_a_stiff_post_follows_its_bump():
    h = 1e-4
    times = np.arange(5001) * h
    x = _post().history(5000, h)[:, 0]
    bump = np.where((times >= 0.2) & (times <= 0.3), 0.05 * np.sin(np.pi * (times - 0.2) / 0.1), 0)
    # the mass rides on the base, lagging by about 2 sqrt(m / k) = 2e-4 s (1.6 m/s peak rate)
    assert np.max(np.abs(x - bump)) < 5e-3 * 0.05
    assert np.all(x[times < 0.2] == 0.0) and abs(x[-1]) < 1e-6  # still before, back after
    # the nonlinear path (Newton on the ground law relative to the base) agrees
    nonlinear = _post(k1=1e-6).history(5000, h)[:, 0]
    assert np.max(np.abs(nonlinear - x)) < 1e-12
