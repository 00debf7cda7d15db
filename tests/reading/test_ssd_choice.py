"""An archive with several system structures: SystemStructure.ssd by default (with a
warning naming the others), ``--ssd NAME`` chooses, ``dsim info`` lists them."""
import zipfile

import dsim
from dsim.master.tools.cli import main


def _two_structures(built, tmp_path):
    """spring_mass_linear's archive with a second .ssd that stops at 0.05 s."""
    source = built["ssp"] / "spring_mass_linear.ssp"
    archive = tmp_path / "two.ssp"
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(archive, "w") as new:
        for name in old.namelist():
            new.writestr(name, old.read(name))
        text = old.read("SystemStructure.ssd").decode()
        start = text.index('stopTime="') + len('stopTime="')
        short = text[:start] + "0.05" + text[text.index('"', start):]
        new.writestr("Short.ssd", short)
    return archive


def test_the_default_structure_is_read_and_the_others_are_named(built, tmp_path, capsys):
    archive = _two_structures(built, tmp_path)
    assert main(["validate", str(archive)]) == 0
    err = capsys.readouterr().err
    assert "holds other system structures too (Short.ssd)" in err
    assert main(["validate", str(archive), "--strict"]) == 2
    assert main(["info", str(archive)]) == 0
    out = capsys.readouterr().out
    assert "system structures: Short.ssd, SystemStructure.ssd" in out
    assert "0 .. 10 s" in out


def test_ssd_chooses_the_structure(built, tmp_path, capsys):
    archive = _two_structures(built, tmp_path)
    result = dsim.simulate(archive, ssd="Short.ssd", out=tmp_path / "r.csv")
    assert result.status == "completed" and result.time == 0.05 and result.steps == 5
    assert main(["info", str(archive), "--ssd", "Short.ssd"]) == 0
    assert "0 .. 0.05 s" in capsys.readouterr().out


def test_a_structure_that_is_not_there_or_outside_is_one_line(built, tmp_path, capsys):
    archive = _two_structures(built, tmp_path)
    for name, expected in (("Nope.ssd", "archive has no Nope.ssd at its root (it has: "
                                        "Short.ssd, SystemStructure.ssd)"),
                           ("../x.ssd", "give the name of an .ssd file at the scene's root")):
        assert main(["run", str(archive), "--ssd", name, "--out", str(tmp_path / "r.csv")]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0], lines
