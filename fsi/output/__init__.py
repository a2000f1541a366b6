"""What a run measures and writes, and what reads it back: the metrics of a step
(:mod:`.metrics`), the run's files (:mod:`.io`, :mod:`.provenance`), reports and plots
(:mod:`.report`, :mod:`.plot`, :mod:`.units`) and the oscillation analysis of a metrics table
(:mod:`.oscillation`).
"""
