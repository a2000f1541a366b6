"""Numerics with no physics in them: one Newton solver for every nonlinear problem
(:mod:`.newton`) and the time schedule and time-integration weights (:mod:`.timestepping`).
"""
