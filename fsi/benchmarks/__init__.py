"""The benchmarks: exact and semi-analytic solutions the verification tests compare with
(hgo_tube, womersley_tube; numpy and scipy only, independent of the UFL forms they check), the
analysis of periodic signals against reference values (oscillation), and the benchmark drivers
that run a case through ``fsi run`` and compare it with its reference (turek_hron,
elastic_tube; the commands scripts/benchmark_turek_hron.py and scripts/benchmark_tube.py).
"""
