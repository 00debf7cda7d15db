"""What tests/checks/test_kernels.py runs in a process of its own under one OpenBLAS kernel:
the four bar's monolithic twins and ``dsim regress`` of the singular-point scenes.

``python -m tests.support.kernel_check OUT`` writes OUT/twin_fixed.csv, OUT/twin_penalized.csv,
OUT/twin_flexible.csv and the regress results into OUT/regress/, prints the kernel numpy
runs on, and exits with regress's code (0: every scene within its band)."""
from __future__ import annotations

import sys
from pathlib import Path

from tests.support.paths import ROOT

SCENES = ("four_bar_singular_fixed", "four_bar_singular_flexible", "four_bar_singular_penalized")


def main(out: Path) -> int:
    from dsim.build_fmus.twins import TWINS, twin_csv
    from dsim.master.tools.cli import main as dsim

    out.mkdir(parents=True, exist_ok=True)
    for joints in ("fixed", "penalized", "flexible"):
        scene = f"four_bar_singular_{joints}"
        assert scene in TWINS
        (out / f"twin_{joints}.csv").write_bytes(twin_csv(scene))
    arguments = ["regress", str(ROOT / "build" / "ssp"), "--baselines",
                 str(ROOT / "regression" / "baselines"), "--results", str(out / "regress")]
    for scene in SCENES:
        arguments += ["--scene", scene]
    return dsim(arguments)


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
