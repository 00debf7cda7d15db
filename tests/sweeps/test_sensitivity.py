"""Honest sensitivity tables: SRC intervals are the least-squares ones, and correlated
factors are said, with SRC^2 not called a variance share (master/sweeps/sensitivity.py)."""
import re

import numpy as np
import pytest

from dsim.master.sweeps import sensitivity
from dsim.master.sweeps.design import Design, parse_vary


def test_src_intervals_are_the_least_squares_ones():
    """One factor: the SRC is Pearson's r and its interval the slope's standard error
    of scipy's linregress on the standardized data, times Student's t."""
    from scipy import stats

    rng = np.random.default_rng(4)
    x = rng.uniform(size=(20, 1))
    y = 2 * x[:, 0] + rng.normal(scale=0.5, size=20)
    coefficients, halves, r2 = sensitivity.src_with_intervals(x, y)
    fit = stats.linregress((x[:, 0] - x.mean()) / x.std(), (y - y.mean()) / y.std())
    assert coefficients[0] == pytest.approx(fit.slope, rel=1e-12)
    assert halves[0] == pytest.approx(fit.stderr * stats.t.ppf(0.975, 18), rel=1e-9)
    assert r2 == pytest.approx(fit.rvalue ** 2, rel=1e-12)


def test_correlated_factors_are_said_and_src_squared_is_no_variance_share():
    """Two factors correlated at r = 0.8 in the sample: the table says so and does not
    call SRC^2 a variance share; a third factor with no effect is marked ~0."""
    rng = np.random.default_rng(1)
    a = rng.uniform(size=40)
    b = 0.8 * a + 0.6 * rng.uniform(size=40)
    c = rng.uniform(size=40)
    configurations = [{"p.a": float(u), "p.b": float(v), "p.c": float(w)}
                      for u, v, w in zip(a, b, c)]
    design = Design([parse_vary("p.a=0:1", True), parse_vary("p.b=0:1.4", True),
                     parse_vary("p.c=0:1", True)], "lhs", 40, 0)
    y = a + b + 0.01 * rng.normal(size=40)
    indices = sensitivity.analyse(design, configurations, {"k": y})
    r = np.corrcoef(a, b)[0, 1]
    assert r > sensitivity.CORRELATED
    caution = sensitivity.cautions(indices, "k")
    assert len(caution) == 1 and f"r = {r:.3f}" in caution[0]
    srcs = {i.factor: i for i in indices if i.measure == "SRC"}
    assert f"add up to {sum(i.value ** 2 for i in srcs.values()):.2f}" in caution[0]
    text = sensitivity.markdown(indices)
    assert "variance share where" not in text and "not a variance share here" in text
    assert srcs["p.c"].spans_zero and not srcs["p.a"].spans_zero
    assert re.search(r"\| p\.c \| -?0\.\d{3} ± 0\.\d{3} ~0 \|", text), text
    assert "~0: its 95 % confidence interval spans zero" in text
    # uncorrelated factors keep the reading of SRC^2 as a share
    plain = sensitivity.analyse(design, [{**p, "p.b": float(v)} for p, v in
                                         zip(configurations, rng.uniform(size=40))],
                                {"k": a + 0.01 * rng.normal(size=40)})
    assert not sensitivity.cautions(plain, "k")
    assert "variance share where R^2 is close to 1" in sensitivity.markdown(plain)
