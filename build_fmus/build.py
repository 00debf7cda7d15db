"""Build every FMU of fmus/ with pythonfmu and pack every scene of ssp/ into an
.ssp archive holding its FMUs; skip what is up to date.

Both folders travel with the installed package (dsim.fmus, and dsim.ssp as data), so
``dsim build-fmus --out DIR`` works from a wheel as from a checkout: DIR/fmus/*.fmu,
DIR/ssp/*.ssp and DIR/references/*.csv (the monolithic twins packed into the scenes).
The default DIR is build/ in a checkout, ./build when dsim is installed.

pythonfmu writes no ModelStructure/InitialUnknowns, which FMI 2.0 requires for
outputs that are calculated at initialization (``fmpy validate`` flags it), so
the built modelDescription.xml is completed here; so are the units, which pythonfmu
does not write either (:mod:`dsim.build_fmus.units`).
"""
from __future__ import annotations

import argparse
import re
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

from lxml import etree
from dsim.build_fmus.units import add_units

#: the folder that holds fmus/ and ssp/: the checkout, or the installed dsim package
ROOT = Path(__file__).resolve().parent.parent

#: FMU model identifier -> the pythonfmu script that defines it.
FMU_SCRIPTS = {
    "SpringMass": "fmus/spring_mass/spring_mass_fmu.py",
    "ElasticBody": "fmus/elastic/elastic_body_fmu.py",
    "Linkage2D": "fmus/linkage/linkage_fmu.py",
    "FlexibleLink2D": "fmus/flexible_link/flexible_link_fmu.py",
}
#: An import of another subpackage of fmus (absolute, or relative from a subpackage).
_IMPORT = re.compile(r"^\s*(?:from|import)\s+(?:fmus\.|\.\.)(\w+)", re.MULTILINE)
SSD_NS = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription"}


def _newest(paths) -> float:
    return max((p.stat().st_mtime for p in paths if p.is_file()), default=0.0)


def default_out(root: Path = ROOT) -> Path:
    """Where ``dsim build-fmus`` builds without --out: build/ of a checkout, or ./build
    when dsim is installed (never inside the installed package)."""
    return root / "build" if (root / "pyproject.toml").is_file() else Path.cwd() / "build"


def _shown(path: Path) -> str:
    """A path as the build's messages show it: from the current folder when inside it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def _sources(root: Path) -> list[Path]:
    files = [p for p in (root / "fmus").rglob("*") if p.is_file()
             and "__pycache__" not in p.parts and p.suffix != ".pyc"]
    return files + [Path(__file__), Path(__file__).with_name("units.py")]


def _complete_model_description(fmu: Path) -> None:
    """Add ModelStructure/InitialUnknowns listing every output (FMI 2.0 3.3.1), and the
    units of every Real variable with their UnitDefinitions (FMI 2.0 2.2.2)."""
    with zipfile.ZipFile(fmu) as archive:
        entries = {name: archive.read(name) for name in archive.namelist()}
    root = etree.fromstring(entries["modelDescription.xml"])
    variables = root.find("ModelVariables")
    outputs = [str(i + 1) for i, v in enumerate(variables) if v.get("causality") == "output"]
    structure = root.find("ModelStructure")
    if structure.find("InitialUnknowns") is None and outputs:
        unknowns = etree.SubElement(structure, "InitialUnknowns")
        for index in outputs:
            etree.SubElement(unknowns, "Unknown", index=index)
    add_units(root, root.find("CoSimulation").get("modelIdentifier"))
    etree.indent(root, space="\t")
    entries["modelDescription.xml"] = etree.tostring(root, xml_declaration=True,
                                                     encoding="UTF-8", pretty_print=True)
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in entries.items():
            archive.writestr(name, data)


def fmu_packages(identifier: str, root: Path = ROOT) -> list[str]:
    """The subpackages of fmus/ an FMU needs: its script's, and those it imports
    (transitively). The top-level modules of fmus/ (the interface, the FMI binding)
    always go in; other subpackages stay out, so each FMU carries only its own code."""
    needed, queue = set(), [Path(FMU_SCRIPTS[identifier]).parts[1]]
    while queue:
        package = queue.pop()
        if package in needed or not (root / "fmus" / package).is_dir():
            continue
        needed.add(package)
        for source in (root / "fmus" / package).rglob("*.py"):
            queue += _IMPORT.findall(source.read_text())
    return sorted(needed)


def build_fmu(identifier: str, root: Path = ROOT, out: Path | None = None) -> Path:
    """Build one FMU into ``out`` (default build/fmus) and return its path."""
    from pythonfmu.builder import FmuBuilder

    out = out or root / "build" / "fmus"
    out.mkdir(parents=True, exist_ok=True)
    target = out / f"{identifier}.fmu"
    with tempfile.TemporaryDirectory(prefix="dsim-fmu-") as temp:
        # the fmus package goes into the FMU's resources: its top-level modules and the
        # subpackages this FMU needs, without caches (a scene's mesh files are the
        # scene's: resources/meshes/ in its .ssp)
        package = Path(temp) / "fmus"
        package.mkdir()
        for module in (root / "fmus").glob("*.py"):
            shutil.copy2(module, package / module.name)
        for name in fmu_packages(identifier, root):
            shutil.copytree(root / "fmus" / name, package / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        # pythonfmu imports the script to find its model class, from the script's own
        # folder: the script sits beside that copy, where `fmus` is top-level as in the
        # FMU (installed, fmus is dsim.fmus); what the import left behind goes after
        script = Path(temp) / Path(FMU_SCRIPTS[identifier]).name
        shutil.copy2(root / FMU_SCRIPTS[identifier], script)
        path, modules = list(sys.path), set(sys.modules)
        try:
            FmuBuilder.build_FMU(script, dest=target, project_files=[package],
                                 canGetAndSetFMUstate=True, canSerializeFMUstate=True)
        finally:
            sys.path[:] = path
            for name in set(sys.modules) - modules:
                if name == script.stem or name == "fmus" or name.startswith("fmus."):
                    del sys.modules[name]
    _complete_model_description(target)
    return target


def build_fmus(root: Path = ROOT, force: bool = False, log=print,
               out: Path | None = None) -> list[Path]:
    """Build every FMU whose sources changed since it was built, into ``out``/fmus
    (default ``root``/build/fmus)."""
    fmu_dir = Path(out or root / "build") / "fmus"
    newest = _newest(_sources(root))
    built = []
    for identifier in FMU_SCRIPTS:
        target = fmu_dir / f"{identifier}.fmu"
        if force or not target.is_file() or target.stat().st_mtime < newest:
            log(f"building {_shown(target)}")
            build_fmu(identifier, root, fmu_dir)
        built.append(target)
    return built


def pack_scene(folder: Path, fmu_dir: Path, out: Path) -> Path:
    """Zip one scene folder with the FMUs its SystemStructure.ssd references."""
    ssd = folder / "SystemStructure.ssd"
    sources = {c.get("source") for c in
               etree.parse(str(ssd)).getroot().iterfind(".//ssd:Component", SSD_NS)}
    target = out / f"{folder.name}.ssp"
    out.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(target, "w", zipfile.ZIP_DEFLATED) as archive:
        for file in sorted(folder.rglob("*")):
            if file.is_file():
                archive.write(file, file.relative_to(folder).as_posix())
        # (a table component's .csv or .mat file is a file of the folder, packed above)
        for source in sorted(s for s in sources if s and not s.lower().endswith(
                (".csv", ".mat"))):
            fmu = fmu_dir / Path(source).name
            if not fmu.is_file():
                raise FileNotFoundError(f"{ssd}: component source '{source}' is not a "
                                        f"built FMU ({fmu} missing)")
            archive.write(fmu, source)
        reference = fmu_dir.parent / "references" / f"{folder.name}.csv"
        if reference.is_file():  # the monolithic twin's results (build_fmus/twins/)
            archive.write(reference, "resources/reference.csv")
    return target


def pack_scenes(root: Path = ROOT, force: bool = False, log=print,
                out: Path | None = None) -> list[Path]:
    """Pack every scene folder of ``root``/ssp that changed since it was packed, with
    the FMUs of ``out``/fmus, into ``out``/ssp (default ``root``/build)."""
    out = Path(out or root / "build")
    fmu_dir, references = out / "fmus", out / "references"
    newest_fmu = _newest(fmu_dir.glob("*.fmu"))
    packed = []
    for folder in sorted(p for p in (root / "ssp").iterdir()
                         if (p / "SystemStructure.ssd").is_file()):
        target = out / "ssp" / f"{folder.name}.ssp"
        newest = max(_newest(folder.rglob("*")), newest_fmu)
        if force or not target.is_file() or target.stat().st_mtime < newest:
            log(f"packing {_shown(target)}")
            try:
                write_twin(folder.name, references)
            except ArithmeticError as error:
                # the twin is a reference for sweeps, not part of the scene: the scene
                # is packed without one and the build goes on (dsim sweep then needs
                # --reference); the tests compute the twins again and say what failed
                (references / f"{folder.name}.csv").unlink(missing_ok=True)
                log(f"dsim build-fmus: {folder.name}: no monolithic reference packed "
                    f"(its computation failed: {error})")
            pack_scene(folder, fmu_dir, out / "ssp")
        packed.append(target)
    return packed


def write_twin(scene: str, out: Path) -> None:
    """Write the scene's monolithic twin (:mod:`dsim.build_fmus.twins`) as
    ``out/SCENE.csv``, where it has one."""
    # here, not at the top: every `dsim` command reads this module to register
    # `dsim build-fmus`, and the twins' finite-element imports take a quarter second
    from dsim.build_fmus.twins import TWINS, twin_csv

    if scene in TWINS:
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{scene}.csv").write_bytes(twin_csv(scene))


def _command(args) -> int:
    return _build_all(args.force, args.out)


def _build_all(force: bool, out: str | None = None) -> int:
    """Build the FMUs and pack the scenes into ``out`` (default: :func:`default_out`);
    a failure is one line and exit 1 (a build that cannot run pythonfmu or write its
    folder is not a bug of the user's input)."""
    out = Path(out) if out else default_out()
    try:
        build_fmus(force=force, out=out)
        pack_scenes(force=force, out=out)
    except (OSError, RuntimeError, etree.LxmlError,
            zipfile.BadZipFile) as error:
        print(f"dsim build-fmus: failed: {error}", file=sys.stderr)
        return 1
    return 0


def register_command(commands) -> None:
    """Add ``dsim build-fmus`` to the command line (entry point ``dsim.commands``)."""
    build_parser = commands.add_parser("build-fmus", help="build dsim's FMUs from fmus/ and "
                                       "pack the scenes of ssp/ (skips what is up to date)")
    _add_options(build_parser)
    build_parser.set_defaults(handler=_command)


def _add_options(parser) -> None:
    parser.add_argument("--force", action="store_true", help="rebuild everything")
    parser.add_argument("--out", metavar="DIR", help="build into DIR/fmus, DIR/ssp and "
                        "DIR/references (default: build/ of the checkout, or ./build "
                        "when dsim is installed)")


def main(argv=None) -> int:
    """Command line: build FMUs then pack scenes."""
    parser = argparse.ArgumentParser(prog="dsim build-fmus", description=__doc__.split("\n")[0])
    _add_options(parser)
    args = parser.parse_args(argv)
    return _build_all(args.force, args.out)


if __name__ == "__main__":
    sys.exit(main())
