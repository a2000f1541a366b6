#!/usr/bin/env python3
"""The study's cases in the plane, axisymmetric and 3D models, side by side
(docs/axisymmetric.md, "The study, axisymmetric"; docs/3d.md).

The code and its usage: fsi.study.models (fsi/study/models.py).
"""

import sys

from fsi.study import models

if __name__ == "__main__":
    sys.exit(models.main())
