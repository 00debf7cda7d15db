"""Damaged scene files: seeded mutations of the shipped scenes' .ssd, .ssv and .ssm (a
byte flipped, an attribute set to an odd value, an element deleted or duplicated), each
checked by ``dsim validate``: it answers 0 (valid) or 2 (one line per problem, naming
the file), never 1 and never a traceback.  Reproducible: the seed of each case is in its
failure message."""
import os
import random
import shutil
from pathlib import Path

import pytest
from lxml import etree

from dsim.master.tools.cli import main
from tests.support.paths import ROOT

#: scenes whose validation is quick (their FMUs' libraries are checked as bytes)
SCENES = ("spring_mass_nonlinear", "chain_10", "four_bar_singular_fixed",
          "crank_slider_penalized", "frame_nested", "four_post_fixed")
CASES = 400
#: cases also run (a few steps each, in a process of their own)
RUN_CASES = 12
RUN_SCENES = ("spring_mass_nonlinear", "chain_10", "four_bar_singular_fixed")
ODD_VALUES = ("", "-1", "nan", "inf", "1e999", "0", "x" * 300, "../../etc/passwd",
              "/absolute", "\u00e9\u00e8", "1.0.0", "true", "2.0", " ")


def _scene_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.suffix in (".ssd", ".ssv", ".ssm"))


def _mutate(data: bytes, rng: random.Random) -> bytes:
    """One mutation of an XML file's bytes (see the module docstring)."""
    kind = rng.choice(("flip", "attribute", "delete", "duplicate"))
    if kind == "flip" or not data.strip():
        position = rng.randrange(len(data))
        return data[:position] + bytes([data[position] ^ (1 << rng.randrange(8))]) \
            + data[position + 1:]
    root = etree.fromstring(data)
    elements = [e for e in root.iter() if isinstance(e.tag, str)]
    element = rng.choice(elements)
    if kind == "attribute" and element.attrib:
        name = rng.choice(sorted(element.attrib))
        element.set(name, rng.choice(ODD_VALUES))
    elif kind == "delete" and element is not root:
        element.getparent().remove(element)
    elif element is not root:
        element.addnext(etree.fromstring(etree.tostring(element)))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8")


def _damaged_copy(scene: Path, folder: Path, rng: random.Random) -> Path:
    """A copy of ``scene`` at ``folder`` (its FMUs hard-linked) with one file mutated;
    the file mutated."""
    shutil.copytree(scene, folder, ignore=shutil.ignore_patterns("*.fmu"))
    for fmu in (scene / "resources").glob("*.fmu"):  # hard links: copies would be slow,
        os.link(fmu, folder / "resources" / fmu.name)  # and a symlink leaves the scene
    target = rng.choice(_scene_files(folder))
    target.write_bytes(_mutate(target.read_bytes(), rng))
    return target


@pytest.fixture(scope="module")
def unpacked(built, tmp_path_factory):
    """The chosen scenes' archives unpacked once (the FMUs and meshes they need)."""
    import zipfile

    base = tmp_path_factory.mktemp("fuzz-scenes")
    for scene in SCENES:
        with zipfile.ZipFile(built["ssp"] / f"{scene}.ssp") as archive:
            archive.extractall(base / scene)
    return base


def test_validate_answers_every_damaged_scene_in_one_line(unpacked, tmp_path, capsys):
    rng = random.Random(20261125)
    failures, codes = [], []
    for case in range(CASES):
        seed = rng.randrange(2 ** 32)
        case_rng = random.Random(seed)
        scene = unpacked / case_rng.choice(SCENES)
        folder = tmp_path / f"case{case}"
        target = _damaged_copy(scene, folder, case_rng)
        try:
            code = main(["validate", str(folder)])
        except SystemExit as exit_:  # argparse and friends
            code = exit_.code
        except Exception as error:  # noqa: BLE001 - the finding itself
            failures.append(f"seed {seed} ({target.relative_to(folder)}): "
                            f"{type(error).__name__}: {error}")
            continue
        err = capsys.readouterr().err
        codes.append(code)
        if code not in (0, 2):
            failures.append(f"seed {seed} ({target.relative_to(folder)}): exit {code}: {err}")
        elif code == 2:
            lines = [line for line in err.splitlines() if line.startswith("dsim: error: ")]
            if not lines or "Traceback" in err or any(str(folder) not in line
                                                       for line in lines):
                failures.append(f"seed {seed} ({target.relative_to(folder)}): {err}")
        shutil.rmtree(folder)
    assert not failures, "\n".join(failures[:10])
    # the mutations are not all fatal: a fuzz that only ever met refusals would test nothing
    assert 0.1 * CASES < codes.count(2) < 0.9 * CASES, codes.count(2)


def test_a_run_of_a_damaged_scene_ends_with_its_exit_code(unpacked, tmp_path):
    """A sample run for a few steps: exit 0, 1 or 2, never a traceback or a signal."""
    import subprocess
    import sys

    rng = random.Random(7)
    for case in range(RUN_CASES):
        seed = rng.randrange(2 ** 32)
        case_rng = random.Random(seed)
        folder = tmp_path / f"case{case}"
        target = _damaged_copy(unpacked / case_rng.choice(RUN_SCENES), folder, case_rng)
        done = subprocess.run([sys.executable, "-m", "dsim.master.tools.cli", "run", str(folder),
                               "--stop", "0.02", "--quiet", "--out", str(tmp_path / f"{case}.csv")],
                              cwd=ROOT, capture_output=True, text=True, timeout=120)
        where = f"seed {seed} ({target.relative_to(folder)})"
        assert done.returncode in (0, 1, 2), (where, done.returncode, done.stderr)
        assert "Traceback" not in done.stderr, (where, done.stderr)
