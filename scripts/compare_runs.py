#!/usr/bin/env python3
"""How far one run's answer is from another's: the largest difference of each headline column of
``metrics.csv`` over the steps, relative to the reference run's peak of that column (the measure
of the speed settings against a tight solve: docs/performance.md, tests/test_solver_settings.py).

The code and its usage: fsi.performance.comparison (fsi/performance/comparison.py).
"""

import sys

from fsi.performance import comparison

if __name__ == "__main__":
    sys.exit(comparison.main())
