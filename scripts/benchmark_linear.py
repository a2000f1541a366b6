#!/usr/bin/env python3
"""The linear solves inside the study's Newton iterations, one at a time (issue #11).

The code and its usage: fsi.performance.linear_solves (fsi/performance/linear_solves.py).
"""

import logging

from fsi.performance import linear_solves

if __name__ == "__main__":
    logging.disable(logging.WARNING)  # the solvers' progress (not when imported: tests)
    linear_solves.main()
