"""The study reproduced (docs/study.md): the run list and its runner (reproduce), the runs'
summaries (runs), the analyses that explain the differences from the study (analyses), the
document and its figures (document), the plane, axisymmetric and 3D models side by side
(models) and the wall's compliance read from a run (wall_compliance). The commands are
the thin scripts of scripts/ (reproduce_study.py, compare_models.py, wall_compliance.py).
"""
