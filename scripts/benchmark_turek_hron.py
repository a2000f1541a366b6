#!/usr/bin/env python3
"""Turek–Hron benchmark: run one case through ``fsi run`` and compare it with the reference.

The code and its usage: fsi.benchmarks.turek_hron (fsi/benchmarks/turek_hron.py).
"""

import sys

from fsi.benchmarks import turek_hron

if __name__ == "__main__":
    sys.exit(turek_hron.main())
