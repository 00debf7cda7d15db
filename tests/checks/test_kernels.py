"""The singular-point scenes, their monolithic twins and the regression check under
several OpenBLAS kernels, each in a process of its own: what an AVX-512 machine, an
old SSE3 one or a desktop's AVX2 one computes, seen on any machine.

numpy's OpenBLAS picks its kernels by CPU at run time, so the last bits of a solve
differ between machines; ``OPENBLAS_CORETYPE`` forces one.  Near the four bar's
singular points those bits are amplified the most (docs/reproducibility.md).
"""
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from dsim.master.recording.results import read_columns
from dsim.master.checks.kernel_study import blas_name, kernel_environment, supported_kernels
from tests.support.paths import ROOT

#: the kernels forced (where the CPU has them): an old SSE3 CPU, a desktop's AVX2,
#: AVX-512 (AVX alone, Sandybridge, lies between the first two and is left out for the
#: suite's time; `dsim regress --update` studies every kernel the CPU has, docs/ci.md)
KERNELS = ("Prescott", "Haswell", "SkylakeX")
#: the twins of two kernels agree to this fraction of each column's peak: round-off
#: amplified by the near-singular Newton matrix at the collinear passes (measured:
#: 3e-9 of the peak force at most between Prescott, Sandybridge, Haswell and Zen)
TWIN_RTOL = 1e-7


def _kernels() -> list:
    return [kernel for kernel in KERNELS if kernel in supported_kernels()]


def _run(kernels, tmp_path):
    """Run tests.support.kernel_check under each kernel (None: the default), two at a time:
    kernel -> (exit code, output, its folder)."""
    def one(kernel):
        env = dict(kernel_environment(kernel), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
        out = tmp_path / (kernel or "default")
        done = subprocess.run([sys.executable, "-m", "tests.support.kernel_check", str(out)], cwd=ROOT,
                              env=env, capture_output=True, text=True, timeout=300)
        return done.returncode, done.stdout + done.stderr, out

    with ThreadPoolExecutor(2) as pool:
        return dict(zip(kernels, pool.map(one, kernels)))


@pytest.mark.skipif("openblas" not in blas_name().lower(),
                    reason="numpy is not built on OpenBLAS here")
def test_singular_scenes_pass_and_agree_under_every_kernel(built, tmp_path):
    kernels = _kernels()
    assert len(kernels) >= 2, "a CPU with SSE3 and AVX at least"
    done = _run([None] + kernels, tmp_path)
    for kernel, (code, text, _) in done.items():
        assert code == 0, f"OPENBLAS_CORETYPE={kernel}:\n{text}"
        assert "Traceback" not in text
    _, _, default = done[None]
    for kernel in kernels:
        for joints in ("fixed", "penalized", "flexible"):
            ours = read_columns(done[kernel][2] / f"twin_{joints}.csv")
            theirs = read_columns(default / f"twin_{joints}.csv")
            for column in list(theirs)[1:]:
                gap = np.max(np.abs(ours[column] - theirs[column]))
                peak = np.max(np.abs(theirs[column]))
                assert gap <= TWIN_RTOL * peak, (kernel, joints, column, gap, peak)
