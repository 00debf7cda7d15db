"""chain_<n>: n one-mass FMUs glued in a line by fixed joints.

Monolithic reference: fixed joints make the chain one rigid body, a mass n*m on
a spring n*k to ground under the end load, integrated with the same
trapezoidal rule and step; every mass of the glued chain must follow it (the model
is the scene's twin, :mod:`dsim.build_fmus.twins.chain`).
"""
from __future__ import annotations

import numpy as np

from dsim.build_fmus.twins.chain import monolithic


def compare(csv_path, n: int) -> dict:
    """Largest difference of any mass from the reference, absolute (m) and
    relative to the reference's peak."""
    from dsim.master.recording.results import read_csv

    header, data = read_csv(csv_path)
    times = data[:, 0]
    step = times[1] - times[0]
    ref_times, reference = monolithic(n, stop=times[-1], step=step)
    reference = np.interp(times, ref_times, reference)
    columns = [header.index(f"m{i}.x[1]") for i in range(1, n + 1)]
    error = float(np.max(np.abs(data[:, columns] - reference[:, None])))
    peak = float(np.max(np.abs(reference)))
    return {"error": error, "peak": peak, "relative_error": error / peak}
