#!/usr/bin/env python3
"""Benchmark of the fluid solver on the study's rigid-structure stenosis case.

The code and its usage: fsi.performance.fluid_speed (fsi/performance/fluid_speed.py).
"""

import logging
import sys

from fsi.performance import fluid_speed

if __name__ == "__main__":
    # No JIT (distutils) chatter; warnings still show. Not when imported (tests): the setting
    # is the process's, and later tests read the run logs' INFO lines.
    logging.disable(logging.INFO)
    sys.exit(fluid_speed.main())
