"""The Mamdani system against hand computation, the tabulated schedule against the exact one, and its file."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from rov_mav.config import ConfigError
from rov_mav.control.fuzzy import MamdaniSystem, default_rules_path, load_fuzzy


def gauss(x, c, w):
    return np.exp(-0.5 * ((x - c) / w) ** 2)


def test_single_rule_output_is_its_centre():
    fis = MamdaniSystem(np.array([1.0]), np.array([0.5]), np.array([20.0]), np.array([2.0]), output_points=2001)
    for x in (0.2, 1.0, 3.0):
        assert fis.evaluate(np.array(x)) == pytest.approx(20.0, abs=1e-9)


def test_two_rules_against_a_hand_integrated_centroid():
    """min implication, max aggregation, centroid: computed here by adaptive quadrature of the exact aggregate."""
    a, aw = np.array([0.5, 1.0]), np.array([0.3, 0.3])
    b, bw = np.array([10.0, 20.0]), np.array([2.0, 3.0])
    fis = MamdaniSystem(a, aw, b, bw, output_points=4001)
    lo, hi = fis.output_universe[[0, -1]]
    for x in (0.5, 0.7, 0.75, 0.9, 1.0):
        w = gauss(x, a, aw)

        def aggregate(y):
            return max(min(w[0], gauss(y, b[0], bw[0])), min(w[1], gauss(y, b[1], bw[1])))

        num = quad(lambda y: y * aggregate(y), lo, hi, limit=200, points=list(b))[0]
        den = quad(aggregate, lo, hi, limit=200, points=list(b))[0]
        assert fis.evaluate(np.array(x)) == pytest.approx(num / den, rel=2e-4)


def test_symmetric_midpoint_gives_midpoint_output():
    fis = MamdaniSystem(np.array([1.0, 2.0]), np.array([0.4, 0.4]), np.array([10.0, 30.0]), np.array([2.0, 2.0]))
    assert fis.evaluate(np.array(1.5)) == pytest.approx(20.0, abs=1e-6)


def test_shipped_rules_are_appendix_iii():
    fuzzy = load_fuzzy()
    np.testing.assert_array_equal(sorted(fuzzy.systems[0].input_centres), [0.5, 1.0, 2.0, 5.0])
    np.testing.assert_array_equal(sorted(fuzzy.systems[0].output_centres), [10.0, 20.0, 50.0, 100.0])
    np.testing.assert_array_equal(sorted(fuzzy.systems[4].input_centres), [0.5, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(sorted(fuzzy.systems[4].output_centres), [0.1, 0.2, 0.5, 1.0])
    # At each rule centre that rule dominates: gamma within 16 % of its consequent.
    for system in (fuzzy.systems[0], fuzzy.systems[3]):
        out = system.evaluate(system.input_centres)
        np.testing.assert_allclose(out, system.output_centres, rtol=0.16)


def test_rates_are_monotone_and_bounded_by_the_consequents():
    fuzzy = load_fuzzy()
    x = np.linspace(0, 0.1, 400)
    rates = fuzzy.rates(np.stack([x] * 6, -1))
    assert (np.diff(rates, axis=0) >= -1e-9).all()
    for i, system in enumerate(fuzzy.systems):
        assert rates[:, i].min() >= system.output_centres.min() - 1e-9
        assert rates[:, i].max() <= system.output_centres.max() + 1e-9


def test_table_interpolation_tracks_the_exact_system():
    fuzzy = load_fuzzy()
    table, xmax = fuzzy.table, fuzzy.table_xmax
    rng = np.random.default_rng(3)
    raw = rng.uniform(0, 1.3, (500, 6)) * xmax
    exact = fuzzy.rates(raw)
    grid = np.linspace(0, 1, table.shape[1])
    interpolated = np.stack([np.interp(np.minimum(raw[:, i] / xmax[i], 1.0), grid, table[i]) for i in range(6)], -1)
    np.testing.assert_allclose(interpolated, exact, rtol=5e-3)


def test_bad_rule_file_names_file_and_key(tmp_path):
    text = default_rules_path().read_text().replace("input_width: 1.0", "input_width: -1.0")
    bad = tmp_path / "rules.yaml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=r"rules.yaml: groups.translation.rules\[0\].input_width"):
        load_fuzzy(bad)
