#!/usr/bin/env python3
"""Elastic-tube benchmarks of the axisymmetric model (docs/axisymmetric.md).

The code and its usage: fsi.benchmarks.elastic_tube (fsi/benchmarks/elastic_tube.py).
"""

import sys

from fsi.benchmarks import elastic_tube

if __name__ == "__main__":
    sys.exit(elastic_tube.main())
