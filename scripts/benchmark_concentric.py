#!/usr/bin/env python3
"""The concentric stenosis in 3D against the axisymmetric model (docs/3d.md).

The code and its usage: fsi.benchmarks.concentric_3d (fsi/benchmarks/concentric_3d.py).
"""

import sys

from fsi.benchmarks import concentric_3d

if __name__ == "__main__":
    sys.exit(concentric_3d.main())
