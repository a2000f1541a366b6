"""fsi: partitioned fluid–structure interaction of blood flow in a stenosed artery."""

__version__ = "0.1.0"
