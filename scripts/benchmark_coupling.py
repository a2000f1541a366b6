#!/usr/bin/env python3
"""Benchmark of the partitioned coupling on the moving-wall Carreau stenosis (issue #5).

The code and its usage: fsi.performance.coupling_speed (fsi/performance/coupling_speed.py).
"""

import sys

from fsi.performance import coupling_speed

if __name__ == "__main__":
    sys.exit(coupling_speed.main())
