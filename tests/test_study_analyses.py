"""fsi/study/analyses.py: the estimates and criteria docs/study.md explains the differences
from the study with (the rigid-column velocity, the degree matching a velocity, when a wall
is quasi-static, the compliance verdict), on synthetic summaries whose answers are known."""

import math

import numpy as np
import pytest

from fsi import config
from fsi.study import analyses as study_analyses
from fsi.study import damping_analyses, sensitivity, wall_analyses
from fsi.study import runs as study_runs

SHIPPED = config.to_dict(config.load(study_runs.ROOT / "configs" / "stenosis_fixed_newtonian.yaml"))
"""The configuration the synthetic runs ran: the shipped fixed-wall Newtonian case."""


def summary(at: dict[float, dict], degree: float = 0.5, **maxima) -> dict:
    """A run summary holding the given report-time values (SI) and maxima, run with the
    shipped fixed-wall Newtonian configuration."""
    return {
        "name": "synthetic",
        "config": SHIPPED,
        "case": {
            "geometry": {
                "length": 0.02,
                "height": 0.007,
                "stenosis_length": 0.01,
                "stenosis_degree": degree,
                "cap_thickness": 0.0005,
                "lipid_length": 0.006,
                "stenosis_centre": None,
            },
            "relaxation_time_s": 3e-4,
            "young_modulus": {"wall": 4e6, "cap": 1.6e6, "lipid": 1.6e6},
        },
        "at": {f"{t:g}": values for t, values in at.items()},
        "maxima": {k: list(v) for k, v in maxima.items()},
        "finished": True,
    }


def test_the_effective_length_is_the_integral_of_h_over_the_lumen():
    """L − l + l / √(1 − d), against a quadrature of H / h(x) over one cosine plaque."""
    L, l, d = 0.02, 0.01, 0.5
    x = np.linspace(0.0, L, 400001)
    bump = np.where(
        np.abs(x - L / 2) <= l / 2, d / 2 * (1 - np.cos(2 * np.pi * (x - L / 4) / l)), 0
    )
    f = 1.0 / (1.0 - bump)
    numeric = np.sum((f[1:] + f[:-1]) / 2 * np.diff(x))  # the trapezoidal rule
    assert study_analyses.effective_length(L, l, d) == pytest.approx(numeric, rel=1e-8)
    assert study_analyses.effective_length(L, l, d) == pytest.approx(L - l + l * math.sqrt(2))


def test_the_rigid_column_lands_on_the_study_s_coarse_maximum():
    """The model notes' calibration: 1200 Pa for 5 ms through a 50 % plaque gives a mean throat
    velocity of 0.234 m/s, the study's coarse Table 1 value at 10 ms to three digits."""
    u = study_analyses.rigid_column_velocity(summary({}), 1200 * 0.005 / 2, 1060.0)
    assert u == pytest.approx(3.0 / (1060 * (0.01 + 0.01 * math.sqrt(2))) / 0.5)
    assert round(u, 3) == 0.234


def test_the_matching_degree_interpolates_between_the_bracketing_runs():
    runs = {
        f"d{d}": summary({0.01: {"peak_velocity": u}}, degree=d)
        for d, u in ((0.4, 0.24), (0.45, 0.25), (0.5, 0.27))
    }
    assert study_analyses.matching_degree(runs, 0.26) == pytest.approx(0.475)
    assert study_analyses.matching_degree(runs, 0.24) == pytest.approx(0.4)
    assert study_analyses.matching_degree(runs, 0.3) is None  # not bracketed


def test_a_wall_is_quasi_static_where_it_moves_as_its_static_compliance_says():
    """|η| / p within a factor 1.5 of the static compliance: 0.44 µm/Pa → 0.29–0.66."""
    c = 4.4e-7
    s = summary(
        {
            0.01: {"peak_displacement": 8e-5, "peak_pressure": 0.27},  # ringing: 300 µm/Pa
            0.02: {"peak_displacement": 3.0e-6, "peak_pressure": 5.0},  # 0.6 µm/Pa
            0.05: {"peak_displacement": 3.0e-6, "peak_pressure": 0.0},  # no pressure: no ratio
        }
    )
    assert [damping_analyses.quasi_static(s, c, t) for t in (0.01, 0.02, 0.05)] == [
        False,
        True,
        False,
    ]
    near, below = (
        summary({0.02: {"peak_displacement": d, "peak_pressure": 5.0}}) for d in (1.5e-6, 1.4e-6)
    )
    assert damping_analyses.quasi_static(near, c, 0.02)  # 0.30 µm/Pa
    assert not damping_analyses.quasi_static(below, c, 0.02)  # 0.28 µm/Pa
    assert not damping_analyses.quasi_static(None, c, 0.02)


def _compliance_text(ratio_per_degree: dict[float, float]) -> str:
    paper = study_runs.paper_values()
    shape = {}
    for d, ratio in ratio_per_degree.items():
        for k, cap in enumerate((1e-4, 2e-4)):
            at = {0.01: {"peak_displacement": ratio * 5.0 * (1 + 1e-5 * k), "peak_pressure": 5.0,
                         "peak_velocity": 0.25}}  # fmt: skip
            shape[f"plaque_shape/d={d},cap={cap}"] = summary(at, degree=d)
    main = {"fixed_newtonian_coarse": shape[f"plaque_shape/d={0.5},cap={1e-4}"]}
    static = {"fixed_wall": 4e-10, "moving_wall": 4.4e-7}
    return wall_analyses.compliance(shape, {}, main, paper, static)


def test_the_compliance_verdict_is_the_factor_two_it_states():
    """The study's 0.058 µm/Pa: a reading at 0.02 µm/Pa is not within a factor 2, one at 0.035
    is; the spread over the cap and the lipid pool is reported."""
    far = _compliance_text({0.3: 0.5e-8, 0.5: 1e-8, 0.7: 2e-8})
    assert "**No plausible reading" in far and "2.9× below" in far
    near = _compliance_text({0.5: 1e-8, 0.7: 3.5e-8})
    assert "**A reading within a factor 2" in near
    assert "1.0e-05 (2 runs)" in near


def test_richardson_recovers_the_limit_and_order_of_a_power_law():
    """f(h) = 3 + 0.5 h² on h = 4, 2, 1: order 2, limit 3; a non-monotone sequence has none."""
    order, limit = sensitivity.richardson(3 + 0.5 * 16, 3 + 0.5 * 4, 3 + 0.5)
    assert order == pytest.approx(2.0) and limit == pytest.approx(3.0)
    assert sensitivity.richardson(1.0, 2.0, 1.5) is None
    assert sensitivity.richardson(1.0, 1.0, 1.0) is None


def test_the_plane_stress_reading_is_plane_strain_with_the_equivalent_moduli():
    """For St. Venant–Kirchhoff, Σ₃₃ = 0 eliminates E₃₃ exactly: the in-plane law is plane
    strain's with λ* = 2λμ/(λ + 2μ) and the same μ, i.e. ν' = ν/(1 + ν), E' = E(1 + 2ν)/(1 + ν)²."""
    from fsi.physics.materials import lame
    from fsi.study import reproduce as reproduce_study

    sets = dict(s.split("=") for s in reproduce_study._plane_stress())
    for region, e in (("wall", 4.0e6), ("cap", 1.6e6), ("lipid", 1.6e6)):
        lam, mu = lame(e, 0.45)
        lam2, mu2 = lame(
            float(sets[f"structure.{region}.young_modulus"]),
            float(sets[f"structure.{region}.poisson_ratio"]),
        )
        assert mu2 == pytest.approx(mu, rel=1e-5)
        assert lam2 == pytest.approx(2 * lam * mu / (lam + 2 * mu), rel=1e-5)


def test_what_p10_does_not_depend_on_states_the_largest_change_and_how_pressure_falls():
    """The largest change of p(10 ms) over the variants but the two-sided plaque (reported on
    its own), and p(10 ms) / p(20 ms) beside (u(10 ms) / u(20 ms))², fsi's and the study's."""
    paper = study_runs.paper_values()

    def run(p10: float, p20: float, u10: float = 0.27, u20: float = 0.25) -> dict:
        return summary({0.01: {"peak_pressure": p10, "peak_velocity": u10},
                        0.02: {"peak_pressure": p20, "peak_velocity": u20}})  # fmt: skip

    main = {"fixed_newtonian_coarse": run(4.0, 3.4)}
    p10 = {"p10/no_supg": run(4.1, 3.5), "p10/degree_0.7": run(3.8, 3.3),
           "p10/plaque_both_sides": run(2.0, 1.7)}  # fmt: skip
    text = study_analyses.pressure_at_10ms(p10, main, paper)
    assert "by more than 5.0 %" in text and "lowers it by 50 %" in text
    assert "| no SUPG (the Galerkin form) | 4.1 | +2.5 % | 3.5 |" in text
    assert f"falls {4.0 / 3.4:.3f}-fold from 10 to 20 ms against {(0.27 / 0.25) ** 2:.3f}" in text
    assert "falls 1.258-fold against 1.053" in text  # the study's coarse Table 2 and Table 1
    assert "fsi's yes, the study's no" in text and "holds a part that is not" in text
    main = {"fixed_newtonian_coarse": run(4.0, 3.0)}  # falls faster than u²: no verdict drawn
    text = study_analyses.pressure_at_10ms(p10, main, paper)
    assert "fsi's no, the study's no" in text and "holds a part" not in text
    assert study_analyses.pressure_at_10ms({}, main, paper) == ""


def test_the_element_section_locates_each_peak_and_concludes_from_the_plaque_s_own():
    """The ``element`` analysis: the study's rows from its Tables 1 and 2, fsi's P2–P1 and
    P1–P1 on each mesh with where each peak pressure sits (a P1–P1 coarse peak at the
    outlet's corner is marked †, as issue #47 found), the plaque's own maxima, and a
    conclusion that follows them; nothing without all four runs."""
    paper = study_runs.paper_values()
    times = (0.01, 0.02, 0.05, 0.1)

    def run(p: float, plaque: float | None = None, corner: bool = False) -> dict:
        s = summary({t: {"peak_pressure": p / (100 * t), "peak_velocity": 0.27} for t in times})
        flank = {"value": plaque or p, "x": 0.00582, "y": 0.00023, "place": None}
        peak = {"value": p, "x": 0.02, "y": 0.007, "place": "outlet_corner"} if corner else flank
        s["where"] = {"0.01": {"peak_pressure": peak, "plaque_pressure": flank}}
        s["name"] = "x"
        return s

    element = {"element/p2p1_coarse": run(4.0), "element/p1p1_coarse": run(6.0, 4.2, True),
               "element/p2p1_fine": run(4.0), "element/p1p1_fine": run(4.1)}  # fmt: skip
    main = {"fixed_newtonian_coarse": run(4.1)}
    text = study_analyses.pressure_and_element(element, main, paper)
    assert "| study, coarse | 6.181 | 4.912 | 2.871 | 1.665 | not printed | 0.234 |" in text
    assert "| fsi P1–P1, coarse | 6 † | 3 | 1.2 | 0.6 | (20.00, 7.00) † the outlet's corner" in text
    assert (
        "| fsi P1–P1, coarse | 4.2 | – | – | – | (5.82, 0.23), the plaque's upstream flank |"
        in text
    )
    assert "sits at a boundary in: P1–P1 coarse (the outlet's corner with a wall)" in text
    assert "P1–P1 gives 4.2 Pa on the coarse mesh against P2–P1's 4 (+5.0 %)" in text
    assert "So the element does not explain fsi's lower pressure at 10 ms" in text
    assert "doc.comsol.com" in text  # the source of the study's code's default element
    element["element/p1p1_coarse"] = run(6.0)  # the element moves the plaque's own pressure
    text = study_analyses.pressure_and_element(element, main, paper)
    assert f"the element closes {100 * 2 / 2.181:.0f} % of the gap" in text
    assert "about fsi's difference from the study" in text
    del element["element/p1p1_fine"]
    assert study_analyses.pressure_and_element(element, main, paper) == ""


def test_the_most_plausible_reading_is_counted_beside_the_shipped_one():
    """plausible.count_table: values within 10 % of the study's per quantity and mesh; a
    configuration whose four runs are not all there is "not run"."""
    from fsi.study import plausible

    paper = study_runs.paper_values()

    def runs(factor: float, mesh: str = "coarse") -> dict:  # every value paper × factor
        out = {}
        for c in study_runs.CONFIGS:
            wall, fluid = c.split("_")
            at = {
                t: {
                    column: factor * paper[(q, t, wall, fluid, mesh)]
                    for q, column in study_runs.PAPER_QUANTITY.items()
                }
                for t in study_runs.TIMES
            }
            out[f"{c}_{mesh}"] = summary(at)
        return out

    table = plausible.count_table(runs(1.05), runs(1.2), paper)
    assert "| velocity | 20 of 20 | 0 of 20 | not run | not run |" in table
    assert "| all | 60 of 60 | 0 of 60 | – | – |" in table
    text = plausible._changes(runs(1.05), runs(1.2), paper)
    assert text.startswith("On the coarse mesh the reading brings into the band: none; and ")
    assert text.count("; study ") == 60


def test_the_ring_is_the_frequency_of_the_wall_s_crests_after_the_pulse():
    """A wall ringing at 79 Hz after the 5 ms pulse (|η| of a damped cosine, sampled every
    0.25 ms to 50 ms, then every 1 ms): |η| crests twice a period, the crests past the pulse's
    own peak and within the resolved steps give the frequency to the steps' resolution."""
    case = config.load(study_runs.ROOT / "configs" / "stenosis_moving_newtonian.yaml")
    omega = 2 * math.pi * 79.0
    times = [k * 2.5e-4 for k in range(1, 201)] + [0.05 + k * 1e-3 for k in range(1, 51)]
    rows = [
        {"t": t, "peak_displacement": 1e-4 * math.exp(-40 * t) * abs(math.cos(omega * t)) + 1e-9}
        for t in times
    ]
    found = study_runs.ring(rows, case)
    assert found["hz"] == pytest.approx(79.0, rel=0.01)
    assert 0.005 < found["crests_s"][0] and found["crests_s"][-1] <= 0.05
    assert len(found["crests_s"]) == 6  # 8 crests in (5, 50] ms, the pulse's own one left out
    assert study_runs.ring(rows[:40], case) is None  # to 10 ms: too few crests
