"""Exact and semi-analytic solutions the verification tests and benchmark scripts compare with
(numpy and scipy only: independent of the UFL forms they check)."""
