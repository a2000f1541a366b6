#!/usr/bin/env python3
"""The accuracy test of a speed setting against a time-converged reference (issue #46;
docs/performance.md).

The code and its usage: fsi.performance.accuracy (fsi/performance/accuracy.py).
"""

import sys

from fsi.performance import accuracy

if __name__ == "__main__":
    sys.exit(accuracy.main())
