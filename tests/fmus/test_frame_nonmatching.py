"""frame_nonmatching (seed section 2.2.3): cross members meshed at 0.0125 m, rails at
0.025 m, glued on non-matching edges by moving least squares."""
import numpy as np
import pytest

from dsim.fmus.elastic.frame import monolithic_frame
from dsim.master.api import simulate
from dsim.master.recording.results import read_csv

STOP = 0.01


def test_frame_nonmatching_equals_the_tied_one_piece_frame(built, tmp_path):
    """The reference meshes the frame as one body with the same two element sizes,
    the extra cross-member edge nodes tied linearly to the rail edge: the transfer
    at the default support (1) is that linear tie, so the two agree to the solver's
    precision; frame_split's response differs by the meshes alone."""
    out = tmp_path / "frame_nonmatching.csv"
    statistics = simulate(built["ssp"] / "frame_nonmatching.ssp", out=out, stop=STOP).statistics
    header, data = read_csv(out)
    glued = data[:, header.index("cross_front.load.u_x")]
    tied = monolithic_frame(stop_time=STOP, cross_element_size=0.0125).load_u_x
    split = monolithic_frame(stop_time=STOP).load_u_x
    peak = np.max(np.abs(tied))
    assert peak > 1e-6
    assert np.max(np.abs(glued - tied)) < 1e-8 * peak
    # forces live on the finer (cross-member) side: 9 nodes x 2 dofs on each of 6 edges
    assert sum(".f_" in name for name in header) == 6 * 9 * 2
    assert statistics["iterations"]["max_per_step"] == 2
    # the mesh change itself moves the response (measured: 11% of the peak over 0.2 s)
    mesh_effect = np.max(np.abs(tied - split))
    assert np.max(np.abs(glued - split)) == pytest.approx(mesh_effect, rel=1e-6)
