#!/usr/bin/env python3
"""Reproduce the study (docs/model.md §4, §6): its four configurations on the coarse and
the fine mesh, the whole heartbeat, with the resolved schedule of the shipped configs, plus the
study's printed schedule (5 ms to 0.4 s, 10 ms to 0.8 s) on the coarse mesh; the runs of the
:data:`ANALYSES` that isolate why fsi differs from the study's tables; then write docs/study.md,
docs/study_tables.csv, the runs' summaries (docs/study_runs/) and the figures.

The code and its usage: fsi.study.reproduce (fsi/study/reproduce.py).
"""

import sys

from fsi.study import reproduce

if __name__ == "__main__":
    sys.exit(reproduce.main())
