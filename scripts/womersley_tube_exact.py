#!/usr/bin/env python3
"""The exact linear solution of Womersley flow in a deformable thick-walled tube (issue #28).

The code and its usage: fsi.benchmarks.womersley_tube (fsi/benchmarks/womersley_tube.py).
"""

from fsi.benchmarks import womersley_tube

if __name__ == "__main__":
    womersley_tube.main()
