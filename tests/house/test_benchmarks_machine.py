"""Every benchmark page names the processor it was measured on (benchmarks.machine)."""
import platform

from benchmarks import machine


def test_a_page_names_the_cpu_model_linux_reports(tmp_path):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: AuthenticAMD\n"
                       "model name\t: AMD EPYC   7B13 64-Core Processor\nflags\t: fpu\n\n"
                       "processor\t: 1\nmodel name\t: AMD EPYC 7B13 64-Core Processor\n")
    assert machine(cpuinfo) == f"AMD EPYC 7B13 64-Core Processor, {platform.machine()}"


def test_without_a_model_the_page_names_the_architecture(tmp_path):
    blank = tmp_path / "cpuinfo"
    blank.write_text("processor\t: 0\nmodel name\t:   \n")  # some virtual machines
    assert machine(blank) == platform.machine()
    assert machine(tmp_path / "missing") == platform.machine()  # not Linux
