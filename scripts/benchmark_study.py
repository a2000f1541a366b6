#!/usr/bin/env python3
"""Performance of the study's moving-wall Carreau case across mesh levels and ranks (issue #11).

The code and its usage: fsi.performance.study_speed (fsi/performance/study_speed.py).
"""

import sys

from fsi.performance import study_speed

if __name__ == "__main__":
    sys.exit(study_speed.main())
