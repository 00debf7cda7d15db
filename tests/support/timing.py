"""Where `make test`'s time went: the JUnit XML files its pytest processes wrote, summed
by test folder and listed by costliest file, printed at the end of the run.

pytest's --durations lists single tests by wall time; this adds what a reader planning
the suite needs, the CPU seconds per folder and per file in each process: the processes
run at the same time on two cores, so a test's wall time says how long it waited on the
others as much as what it cost them."""
from __future__ import annotations

import sys
from collections import defaultdict
from pathlib import Path

from lxml import etree


def seconds_by_file(report: Path, cpu: bool = False) -> dict[str, float]:
    """Seconds per test file in one JUnit XML: wall seconds of its tests with their
    set-up and tear-down, or (``cpu``) the CPU seconds tests/conftest.py recorded."""
    files: dict[str, float] = defaultdict(float)
    for case in etree.parse(str(report)).iter("testcase"):
        if cpu:
            spent = case.find("properties/property[@name='cpu']")
            seconds = float(spent.get("value")) if spent is not None else 0.0
        else:
            seconds = float(case.get("time", 0.0))
        # the classname is the module's dotted path, and a test class's name after it
        parts = case.get("classname", "").split(".")
        module = next((k for k, part in enumerate(parts) if part.startswith("test_")),
                      len(parts) - 1)
        files["/".join(parts[:module + 1]) + ".py"] += seconds
    return dict(files)


def main(reports: list[str]) -> None:
    """Print, per pytest process, its wall and CPU totals, its CPU per folder and the
    files that took the most."""
    for report in map(Path, reports):
        if not report.exists():
            print(f"{report}: not written (that process did not end normally)")
            continue
        files, cpu = seconds_by_file(report), seconds_by_file(report, cpu=True)
        folders: dict[str, float] = defaultdict(float)
        for name, seconds in cpu.items():
            folders[name.rsplit("/", 1)[0]] += seconds
        print(f"{report.stem}: {sum(files.values()):.0f} s in tests, "
              f"{sum(cpu.values()):.0f} s of CPU; CPU by folder: " + ", ".join(
                  f"{folder} {seconds:.0f}" for folder, seconds in
                  sorted(folders.items(), key=lambda item: -item[1])))
        costliest = sorted(cpu.items(), key=lambda item: -item[1])[:8]
        print("  the most CPU: " + ", ".join(f"{name} {seconds:.0f}"
                                             for name, seconds in costliest))


if __name__ == "__main__":
    main(sys.argv[1:])
