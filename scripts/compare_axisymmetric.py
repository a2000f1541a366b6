#!/usr/bin/env python3
"""The study's four cases in the plane and the axisymmetric model, side by side
(docs/axisymmetric.md, "The study, axisymmetric").

The code and its usage: fsi.study.axisymmetric (fsi/study/axisymmetric.py).
"""

import sys

from fsi.study import axisymmetric

if __name__ == "__main__":
    sys.exit(axisymmetric.main())
