"""Speed measurements (docs/performance.md): the coupled loop (coupling_speed), the fluid solver
(fluid_speed), the linear solves (linear_solves), the study's case across mesh levels and ranks
(study_speed), with their profiler (profiling); and how far a faster setting's answer is from a
tight solve's (comparison). The commands are the thin scripts scripts/benchmark_coupling.py,
benchmark_fluid.py, benchmark_linear.py, benchmark_study.py and compare_runs.py.
"""
