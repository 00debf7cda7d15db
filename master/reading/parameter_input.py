"""Model parameters as a user writes them for ``dsim run``: ``--set NAME=VALUE``
(repeatable) and ``--set-file FILE``, an SSP parameter set (.ssv), a CSV of
``name,value`` rows or a JSON object of name -> value.  Values stay text (or JSON's
numbers, booleans and strings): :mod:`dsim.master.planning.parameters` reads each by its
variable's type and checks it."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from lxml import etree

from dsim.master.errors import InputError
from dsim.master.reading.small_files import bounded_bytes, parse_untrusted, utf8_text
from dsim.master.reading.ssp import _check_schema
from dsim.master.reading.ssp_values import parameter_set


def parse_assignments(texts) -> dict:
    """name -> value text of ``NAME=VALUE`` texts (a later one wins); InputError
    naming every text that is not one."""
    values, problems = {}, []
    for text in texts or ():
        name, equals, value = text.partition("=")
        if not equals or not name.strip():
            problems.append(f"--set '{text}': give NAME=VALUE (COMPONENT.VARIABLE=VALUE, "
                            "or JOINT.k0=VALUE)")
            continue
        values[name.strip()] = value
    if problems:
        raise InputError(problems)
    return values


def _ssv(path: Path, text: bytes) -> dict:

    try:
        root = parse_untrusted(text)
    except etree.XMLSyntaxError as error:
        raise InputError(f"{path}: malformed XML: {error}") from None
    problems, warnings = [], []
    _check_schema(root, str(path), "SystemStructureParameterValues.xsd", problems, warnings)
    values = parameter_set(root, str(path), problems)
    if problems:
        raise InputError(problems)
    return {name: value for name, (_, value) in values.items()}


def _csv(path: Path, text: str) -> dict:
    values, problems = {}, []
    for number, row in enumerate(csv.reader(io.StringIO(text)), start=1):
        if not row or all(not cell.strip() for cell in row) or row[0].lstrip().startswith("#"):
            continue
        if number == 1 and [cell.strip().lower() for cell in row] == ["name", "value"]:
            continue  # a header
        if len(row) != 2 or not row[0].strip():
            problems.append(f"{path} line {number}: give two fields, name and value "
                            f"(got {len(row)})")
            continue
        values[row[0].strip()] = row[1]
    if problems:
        raise InputError(problems)
    return values


def _json(path: Path, text: str) -> dict:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise InputError(f"{path}: not JSON: {error}") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: give a JSON object of name -> value, not a "
                         f"{type(data).__name__}")
    problems = [f"{path}: '{name}': a value must be a number, true/false or text (a joint's "
                "k0 may be a list of numbers)" for name, value in data.items()
                if isinstance(value, (dict, type(None)))]
    if problems:
        raise InputError(problems)
    return data


#: the largest parameter file read (a file of values, not a data set)
MAX_BYTES = 16 * 1024 * 1024


def read_parameter_file(path) -> dict:
    """name -> value of a parameter file, by its suffix: .ssv (an SSP parameter set:
    names as a set bound to the root system writes them), .csv or .json."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".ssv", ".csv", ".json"):
        raise InputError(f"{path}: a parameter file is .ssv (SSP parameter set), .csv "
                         "(name,value rows) or .json (an object of name -> value)")
    data = bounded_bytes(path, MAX_BYTES, "a parameter file")
    if suffix == ".ssv":
        return _ssv(path, data)
    text = utf8_text(path, data)
    return _csv(path, text) if suffix == ".csv" else _json(path, text)


def given_parameters(files=(), assignments=()) -> dict:
    """What ``--set-file`` (in order) and then ``--set`` give: a later value wins."""
    values = {}
    for file in files or ():
        values.update(read_parameter_file(file))
    values.update(parse_assignments(assignments))
    return values
