"""Designs of experiments for ``dsim sweep``: what is varied, over which values, and
the points that follow.

A factor is a run setting (``step``, ``tolerance``, ... of :data:`dsim.master.settings.SETTINGS`)
or a model parameter, named by its component's dotted path and the variable
(``left.k``, ``body.plate.thickness``): a name with a dot is a parameter, one without
is a setting.  ``--vary NAME=SPEC`` gives its values:

* ``a,b,c``: a list (numbers or words);
* ``lo:hi:N``: N values evenly spaced from lo to hi, both included;
* ``lo:hi:log:N``: N values evenly spaced in log10 from lo to hi (lo, hi > 0).

A **grid** design is the full-factorial product of every factor's values.  A sampled
design draws ``--samples N`` points from scipy.stats.qmc (``lhs``: Latin hypercube,
``sobol``: scrambled Sobol', ``halton``: scrambled Halton) or from SALib's samplers
(``saltelli``: the N (d + 2) runs that first-order and total Sobol' indices need;
``morris``: N trajectories of d + 1 runs); there a range has no count (``lo:hi`` or
``lo:hi:log``: the design chooses the values, uniform or log-uniform) and a list is
drawn from with equal weight.  ``--seed`` makes the draw reproducible: the same spec
gives the same points.
"""
from __future__ import annotations

import difflib
import itertools
import json
import math
import re
from dataclasses import asdict, dataclass, field

import numpy as np

from dsim.master.errors import InputError
from dsim.master.settings import SETTINGS, convert_setting

#: designs drawn by scipy.stats.qmc
QMC = ("lhs", "sobol", "halton")
#: designs drawn by SALib's samplers for its own analyses
SALIB = ("saltelli", "morris")
DESIGNS = ("grid",) + QMC + SALIB
#: levels of a Morris grid (SALib's default of 4: each trajectory moves by 2/3 of a range)
MORRIS_LEVELS = 4


@dataclass(frozen=True)
class Factor:
    """One varied quantity: ``kind`` is ``list`` (``values``), ``linear`` or ``log``
    (``low`` .. ``high``, ``count`` values on a grid, None when a design samples)."""

    name: str
    kind: str
    values: tuple = ()
    low: float = math.nan
    high: float = math.nan
    count: int | None = None

    @property
    def is_parameter(self) -> bool:
        return is_parameter(self.name)

    @property
    def numeric(self) -> bool:
        """Whether every value is a number (a range always is)."""
        return self.kind != "list" or all(_number(v) is not None for v in self.values)

    def grid_values(self) -> list:
        """The factor's values on a grid."""
        if self.kind == "list":
            return list(self.values)
        if self.kind == "linear":
            return [float(v) for v in np.linspace(self.low, self.high, self.count)]
        values = [float(v) for v in np.logspace(math.log10(self.low), math.log10(self.high),
                                                self.count)]
        values[0], values[-1] = self.low, self.high  # the ends as written, no round-off
        return values

    def value_at(self, unit: float):
        """The value at ``unit`` in [0, 1] of the factor's range (a list: the entry whose
        equal share of [0, 1) holds it)."""
        if self.kind == "list":
            return self.values[min(int(unit * len(self.values)), len(self.values) - 1)]
        if self.kind == "linear":
            return float(self.low + unit * (self.high - self.low))
        return float(10 ** (math.log10(self.low)
                            + unit * (math.log10(self.high) - math.log10(self.low))))

    def coordinate(self, value) -> float:
        """The value where an analysis measures it: log10 on a log range, the number
        itself otherwise (a list of words: the entry's position)."""
        if self.kind == "log":
            return math.log10(float(value))
        number = _number(value)
        if number is None:
            return float(list(self.values).index(value))
        return number

    def spec(self) -> str:
        """The SPEC text of ``--vary`` that gives this factor."""
        if self.kind == "list":
            return ",".join(str(v) for v in self.values)
        words = [repr(self.low), repr(self.high)] + (["log"] if self.kind == "log" else [])
        return ":".join(words + ([str(self.count)] if self.count else []))


def is_parameter(name: str) -> bool:
    """A dotted name is a model parameter (``component.variable``), else a setting."""
    return "." in name


def split(configuration: dict) -> tuple[dict, dict]:
    """A point's (settings, model parameters)."""
    settings = {k: v for k, v in configuration.items() if not is_parameter(k)}
    return settings, {k: v for k, v in configuration.items() if is_parameter(k)}


def _number(text):
    if isinstance(text, bool):
        return None
    try:
        value = float(text)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def _list_value(text: str):
    """A list entry: an int or float where the text is one (a parameter's value is
    checked against its FMU later), else the word."""
    text = text.strip()
    if re.fullmatch(r"[+-]?\d+", text):
        return int(text)
    number = _number(text)
    return number if number is not None else text


def parse_vary(text: str, sampled: bool) -> Factor:
    """The factor of one ``--vary NAME=SPEC`` (see the module docstring); InputError
    naming what is wrong.  ``sampled``: the design draws the values (ranges have no
    count)."""
    name, equals, spec = text.partition("=")
    name, spec = name.strip(), spec.strip()
    where = f"--vary {text}"
    if not equals or not name or not spec:
        raise InputError(f"{where}: write NAME=SPEC (a list a,b,c, a range lo:hi:N or "
                         "lo:hi:log:N)")
    name = name.replace("-", "_") if not is_parameter(name) else name
    if not is_parameter(name) and name not in SETTINGS:
        close = difflib.get_close_matches(name, list(SETTINGS), n=3, cutoff=0.6)
        raise InputError(f"{where}: '{name}' is not a setting"
                         + (f" (closest: {', '.join(close)})" if close else
                            f" ({', '.join(SETTINGS)})")
                         + "; a model parameter is named COMPONENT.VARIABLE")
    if ":" not in spec:
        values = tuple(_list_value(v) for v in spec.split(",") if v.strip())
        if not values:
            raise InputError(f"{where}: no values")
        return Factor(name, "list", values)
    words = [w.strip() for w in spec.split(":")]
    kind = "log" if len(words) > 2 and words[2].lower() == "log" else "linear"
    rest = words[3:] if kind == "log" else words[2:]
    low, high = _number(words[0]), _number(words[1])
    if low is None or high is None or len(rest) > 1:
        raise InputError(f"{where}: a range is lo:hi:N or lo:hi:log:N with numbers lo, hi")
    if kind == "log" and (low <= 0 or high <= 0):
        raise InputError(f"{where}: a log range needs lo and hi greater than 0")
    if low == high:
        raise InputError(f"{where}: the range is empty (lo = hi); give a single value as "
                         "a list")
    if sampled:
        if rest:
            raise InputError(f"{where}: a sampled design chooses the values: give the "
                             "range as lo:hi or lo:hi:log, without a count (the count is "
                             "--samples)")
        return Factor(name, kind, low=low, high=high)
    if not rest or not re.fullmatch(r"\d+", rest[0]) or int(rest[0]) < 2:
        raise InputError(f"{where}: a range on a grid needs a count of at least 2 "
                         "(lo:hi:N or lo:hi:log:N), or a sampled design (--design lhs)")
    return Factor(name, kind, low=low, high=high, count=int(rest[0]))


@dataclass
class Design:
    """The factors, how points are drawn from them (``kind`` of :data:`DESIGNS`),
    ``samples`` and ``seed`` of a sampled design."""

    factors: list = field(default_factory=list)
    kind: str = "grid"
    samples: int | None = None
    seed: int | None = None

    @property
    def sampled(self) -> bool:
        return self.kind != "grid"

    def check(self) -> None:
        """InputError listing every problem of the design itself (values are checked
        against settings here, against the FMUs by the run's own checks)."""
        problems = []
        if self.kind not in DESIGNS:
            problems.append(f"--design {self.kind}: not one of {', '.join(DESIGNS)}")
        names = [f.name for f in self.factors]
        problems += [f"--vary {n}: given twice" for n in sorted({n for n in names
                                                                  if names.count(n) > 1})]
        for factor in self.factors:
            if not factor.is_parameter:
                values = factor.values if factor.kind == "list" else (factor.low, factor.high)
                for value in values:
                    _, problem = convert_setting(factor.name, value, f"sweep: {factor.name}")
                    if problem:
                        problems.append(problem)
        if self.sampled:
            problems += self._sampled_problems()
        elif self.samples is not None:
            problems.append("--samples: a grid has as many points as the product of its "
                            "factors' counts: choose a sampled design (--design lhs, sobol, "
                            "halton, saltelli, morris)")
        if problems:
            raise InputError(list(dict.fromkeys(problems)))

    def _sampled_problems(self) -> list[str]:
        problems = []
        if not self.factors:
            problems.append(f"--design {self.kind}: nothing to sample: give --vary NAME=lo:hi")
        if not self.samples or self.samples < 1:
            problems.append(f"--design {self.kind}: give --samples N (N >= 1)")
        elif self.kind == "sobol" and self.samples & (self.samples - 1):
            below = 1 << (self.samples.bit_length() - 1)
            problems.append(f"--samples {self.samples}: a Sobol' design keeps its balance "
                            f"only at a power of 2: give {below} or {below * 2}")
        elif self.kind == "saltelli" and self.samples & (self.samples - 1):
            below = 1 << (self.samples.bit_length() - 1)
            problems.append(f"--samples {self.samples}: the Saltelli design takes a power "
                            f"of 2 base samples (each costs d + 2 runs): give {below} or "
                            f"{below * 2}")
        if self.kind in SALIB:
            lists = [f.name for f in self.factors if f.kind == "list"]
            if lists:
                problems.append(f"--design {self.kind}: every factor must be a range lo:hi "
                                f"(SALib's analysis needs continuous factors): "
                                f"{', '.join(lists)} is a list")
        return problems

    def units(self) -> np.ndarray:
        """The points in the unit cube, (points, factors)."""
        d = len(self.factors)
        if self.kind == "lhs":
            from scipy.stats import qmc
            return qmc.LatinHypercube(d=d, seed=self.seed).random(self.samples)
        if self.kind == "sobol":
            from scipy.stats import qmc
            return qmc.Sobol(d=d, scramble=True, seed=self.seed).random_base2(
                int(math.log2(self.samples)))
        if self.kind == "halton":
            from scipy.stats import qmc
            return qmc.Halton(d=d, scramble=True, seed=self.seed).random(self.samples)
        problem = self.salib_problem(unit=True)
        if self.kind == "saltelli":
            from SALib.sample import sobol
            return sobol.sample(problem, self.samples, calc_second_order=False,
                                seed=self.seed)
        from SALib.sample import morris
        return morris.sample(problem, self.samples, num_levels=MORRIS_LEVELS,
                             seed=self.seed)

    def salib_problem(self, unit: bool = False) -> dict:
        """SALib's problem: the factors' names and bounds (the unit cube, or each
        factor's analysed coordinates: log10 on a log range)."""
        bounds = [[0.0, 1.0] if unit else [self.factors[k].coordinate(self.factors[k].low),
                                          self.factors[k].coordinate(self.factors[k].high)]
                  for k in range(len(self.factors))]
        return {"num_vars": len(self.factors), "names": [f.name for f in self.factors],
                "bounds": bounds}

    def configurations(self) -> list[dict]:
        """Every point: factor name -> value."""
        if not self.factors:
            return []
        if not self.sampled:
            keys = [f.name for f in self.factors]
            return [dict(zip(keys, values)) for values in
                    itertools.product(*(f.grid_values() for f in self.factors))]
        return [{f.name: f.value_at(float(u)) for f, u in zip(self.factors, row)}
                for row in self.units()]

    def record(self) -> dict:
        """What ``design.json`` keeps of the design (its spec; the points beside it)."""
        return {"kind": self.kind, "samples": self.samples, "seed": self.seed,
                "factors": [asdict(f) | {"values": list(f.values)} for f in self.factors]}

    @classmethod
    def from_record(cls, data: dict) -> "Design":
        return cls([Factor(**(f | {"values": tuple(f["values"])})) for f in data["factors"]],
                   data["kind"], data["samples"], data["seed"])


def describe(record: dict) -> str:
    """A design record in a few words, for a message."""
    factors = ", ".join(f"{f['name']}={Factor(**(f | {'values': tuple(f['values'])})).spec()}"
                        for f in record.get("factors", []))
    extra = (f" {record['samples']} samples seed {record['seed']}"
             if record.get("kind") != "grid" else "")
    return f"{record.get('kind')}{extra} over {factors or 'nothing'}"


def same_json(a, b) -> bool:
    """Equal as JSON would store them (floats and lists compare as written)."""
    return json.loads(json.dumps(a, sort_keys=True)) == json.loads(json.dumps(b, sort_keys=True))
