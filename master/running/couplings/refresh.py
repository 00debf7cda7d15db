"""Lambda refresh policies: when Newton should re-measure the interface flexibility
(a registry; ``refresh=`` names one).

Each is called after an unconverged iteration of a step with ``iteration``
(1-based), ``history`` (max |R| / tolerance of each iteration so far), whether the
step has refreshed already, the cost of a refresh (trial steps of the largest
glued subsystem) and the settings; it answers whether to refresh now.  A coupling
that holds no flexibility yet measures one whatever the policy says.
"""
from __future__ import annotations

import math


def after_iterations(iteration: int, history, refreshed: bool, cost: int, settings) -> bool:
    """The seed's rule: after every ``refresh_after`` iterations of one step."""
    return iteration > 1 and (iteration - 1) % settings.refresh_after == 0


def adaptive(iteration: int, history, refreshed: bool, cost: int, settings) -> bool:
    """The seed's rule, and once per step when Newton has slowed to linear
    convergence (two successive contraction rates alike: a stale Lambda, not the
    superlinear approach of a good one) at a rate that predicts more iterations to
    the tolerance than a refresh costs, or when the residual grows."""
    if after_iterations(iteration, history, refreshed, cost, settings):
        return True
    if refreshed or len(history) < 3 or history[-1] == 0:
        return False
    rate, previous = history[-1] / history[-2], history[-2] / history[-3]
    if rate >= 1.0:
        return True
    if rate < 0.5 * previous:
        return False  # still speeding up
    remaining = math.log(history[-1]) / -math.log(max(rate, 1e-300))
    return remaining > cost + 1


def every_step(iteration: int, history, refreshed: bool, cost: int, settings) -> bool:
    """At the first iteration of every step that has not converged at once (before its
    first correction), and the seed's rule after.  For interfaces whose flexibility
    changes fast from step to step, as a mechanism's near a singular configuration:
    measured around the step's own predicted forces, one Newton correction usually
    ends the step (docs/four_bar_table.md), where an older Lambda contracts slowly or,
    once the flexibility has grown past twice the held one, diverges."""
    return (iteration == 1 and not refreshed) or after_iterations(
        iteration, history, refreshed, cost, settings)


REFRESH_POLICIES = {"adaptive": adaptive, "iterations": after_iterations, "step": every_step}
