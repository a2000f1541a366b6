#!/usr/bin/env python3
"""Is the cap's stress resolved? The concentric plaque's structure alone, its cap stress read
at the DG nodes and from its P1 projection (docs/3d.md).

The code and its usage: fsi.benchmarks.cap_resolution (fsi/benchmarks/cap_resolution.py).
"""

import sys

from fsi.benchmarks import cap_resolution

if __name__ == "__main__":
    sys.exit(cap_resolution.main())
