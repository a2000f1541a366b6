#!/usr/bin/env python3
"""How far a vessel's wall moves per kPa of blood pressure, from a run's field files.

The code and its usage: fsi.study.wall_compliance (fsi/study/wall_compliance.py).
"""

import sys

from fsi.study import wall_compliance

if __name__ == "__main__":
    sys.exit(wall_compliance.main())
